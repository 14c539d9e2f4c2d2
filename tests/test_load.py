import numpy as np
import pytest
import trimesh

from pinchmatch import ConfigError, MeshError, load_mesh


def box(extents=(60.0, 40.0, 20.0)):
    return trimesh.creation.box(extents=extents)


@pytest.mark.parametrize("ext", ["stl", "obj", "ply", "off", "glb"])
def test_every_format_reads_to_the_same_solid(write_mesh, ext):
    units = "mm" if ext == "glb" else None  # glTF defaults to metres
    loaded = load_mesh(write_mesh(box(), f"b.{ext}"), units=units)
    assert loaded.watertight
    assert loaded.mesh.volume == pytest.approx(60 * 40 * 20, rel=1e-9)
    np.testing.assert_allclose(np.ptp(loaded.mesh.vertices, axis=0), [60, 40, 20], atol=1e-6)


def test_gltf_defaults_to_metres_and_y_up(write_mesh):
    loaded = load_mesh(write_mesh(box((0.06, 0.04, 0.02)), "b.glb"))
    assert loaded.units_in == "m" and loaded.up_label == "y"
    np.testing.assert_allclose(np.ptp(loaded.mesh.vertices, axis=0), [60, 40, 20], atol=1e-6)
    np.testing.assert_allclose(loaded.up, [0, 1, 0])


def test_other_formats_default_to_mm_and_z_up(write_mesh):
    loaded = load_mesh(write_mesh(box(), "b.stl"))
    assert loaded.units_in == "mm" and loaded.up_label == "z"


@pytest.mark.parametrize("units, scale", [("cm", 10.0), ("in", 25.4), ("m", 1000.0)])
def test_units_scale_to_mm(write_mesh, units, scale):
    loaded = load_mesh(write_mesh(box((6.0, 4.0, 2.0)), "b.obj"), units=units)
    assert np.ptp(loaded.mesh.vertices, axis=0)[0] == pytest.approx(6.0 * scale)


def test_scene_with_several_meshes_is_one_object(write_mesh):
    a = box((20.0, 20.0, 20.0))
    b = box((20.0, 20.0, 20.0))
    b.apply_translation((50.0, 0, 0))
    scene = trimesh.Scene([a, b])
    loaded = load_mesh(write_mesh(scene, "two.glb"), units="mm")
    assert len(loaded.mesh.faces) == 24
    assert loaded.mesh.volume == pytest.approx(2 * 8000.0)


def test_inside_out_mesh_is_turned_and_reported(write_mesh):
    m = box()
    m.invert()
    loaded = load_mesh(write_mesh(m, "inv.obj"))
    assert loaded.mesh.volume > 0
    assert any("inside-out" in r for r in loaded.repairs)


def test_duplicates_degenerates_and_slivers_are_repaired(write_mesh):
    m = box()
    faces = np.vstack([m.faces, m.faces[:2], [[0, 0, 1]]])  # two duplicates and a degenerate
    sliver = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    sliver.apply_translation((200, 0, 0))
    combined = trimesh.util.concatenate([trimesh.Trimesh(m.vertices, faces, process=False), sliver])
    loaded = load_mesh(write_mesh(combined, "messy.obj"))
    text = " ".join(loaded.repairs)
    assert "duplicate faces" in text and "degenerate" in text and "sliver" in text
    assert len(loaded.mesh.faces) == 12 and loaded.watertight


def test_open_mesh_warns(write_mesh):
    m = box()
    m.update_faces(np.arange(len(m.faces)) != 0)
    loaded = load_mesh(write_mesh(m, "open.obj"))
    assert not loaded.watertight and loaded.warnings


# ---- bad input: each a MeshError naming the file, the problem and the fix
def test_missing_file(tmp_path):
    with pytest.raises(MeshError, match=r"nope\.stl: no such file"):
        load_mesh(tmp_path / "nope.stl")


def test_empty_file(tmp_path):
    (tmp_path / "e.stl").write_bytes(b"")
    with pytest.raises(MeshError, match=r"e\.stl: file is empty.*re-export"):
        load_mesh(tmp_path / "e.stl")


def test_unknown_extension(tmp_path):
    (tmp_path / "m.xyz").write_text("1 2 3\n")
    with pytest.raises(MeshError,
                       match=r"m\.xyz: unknown mesh format '\.xyz'.*export it as one of"):
        load_mesh(tmp_path / "m.xyz")


def test_folder(tmp_path):
    (tmp_path / "d.stl").mkdir()
    with pytest.raises(MeshError, match=r"is a folder"):
        load_mesh(tmp_path / "d.stl")


def test_garbage(tmp_path):
    (tmp_path / "g.stl").write_bytes(bytes(range(256)) * 3)
    with pytest.raises(MeshError, match=r"g\.stl: .*(truncated|corrupt)"):
        load_mesh(tmp_path / "g.stl")


def test_truncated_binary_stl(write_mesh):
    path = write_mesh(box(), "t.stl")
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(MeshError,
                       match=r"t\.stl: truncated binary STL: its header promises 12 triangles"):
        load_mesh(path)


def test_obj_with_bad_indices(tmp_path):
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n")
    with pytest.raises(MeshError, match=r"bad\.obj: a face refers to a vertex that does not exist"):
        load_mesh(tmp_path / "bad.obj")


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_nan_or_inf_vertices(tmp_path, value):
    text = f"v 0 0 0\nv {value} 0 0\nv 0 10 0\nv 0 0 10\nf 1 2 3\nf 1 3 4\nf 1 2 4\nf 2 3 4\n"
    (tmp_path / "n.obj").write_text(text)
    with pytest.raises(MeshError, match=r"n\.obj: 1 of 4 vertices are NaN or infinite"):
        load_mesh(tmp_path / "n.obj")


def test_no_faces(tmp_path):
    (tmp_path / "p.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    with pytest.raises(MeshError, match=r"p\.obj: .*no (faces|triangles)"):
        load_mesh(tmp_path / "p.obj")


def test_mesh_in_metres_read_as_mm_suggests_units(write_mesh):
    # in Python the fix is a keyword argument; the command line names the flag (tests/test_cli.py)
    with pytest.raises(MeshError,
                       match=r'm\.stl: mesh is 0\.06 mm across .*read it with units="m" \(60 mm '
                             r'across\)$'):
        load_mesh(write_mesh(box((0.06, 0.04, 0.02)), "m.stl"))


@pytest.mark.parametrize("size, units, fixes", [
    (0.206, "mm", ['units="m" (206 mm across)']),  # cm would make it 2 mm: not a thing a hand holds
    (60_000.0, "m", ['units="mm" (60 mm across)']),
    # two fit: both named
    (0.5, "mm", ['units="m" (500 mm across)', 'units="in" (12.7 mm across)']),
])
def test_the_units_hint_names_the_units_that_make_a_graspable_size(write_mesh, size, units, fixes):
    name = "a.stl" if units == "mm" else "a.glb"
    mesh = (box((size, size * 0.6, size * 0.3)) if units == "mm"
            else box((size / 1000.0, size * 0.6e-3, size * 0.3e-3)))
    with pytest.raises(MeshError) as info:
        load_mesh(write_mesh(mesh, name), units=units)
    assert str(info.value).endswith("read it with " + " or ".join(fixes)), str(info.value)
    assert "--units" in info.value.cli_message() and "units=" not in info.value.cli_message()


def test_flat_mesh_has_no_volume(tmp_path):
    (tmp_path / "f.obj").write_text("v 0 0 0\nv 10 0 0\nv 0 10 0\nv 10 10 0\nf 1 2 3\nf 2 4 3\n")
    with pytest.raises(MeshError, match=r"f\.obj: the mesh is flat"):
        load_mesh(tmp_path / "f.obj")


def test_bad_units_and_up(write_mesh):
    path = write_mesh(box(), "b.stl")
    with pytest.raises(ConfigError, match="--units: unknown unit 'ft'"):
        load_mesh(path, units="ft")
    with pytest.raises(ConfigError, match="--up: unknown up direction 'w'"):
        load_mesh(path, up="w")


def test_up_directions_are_the_six_unit_axes():
    from pinchmatch.mesh.frames import UP_VECTORS

    assert UP_VECTORS == {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0),
                          "-x": (-1.0, 0.0, 0.0), "-y": (0.0, -1.0, 0.0), "-z": (0.0, 0.0, -1.0)}


def test_parts_inside_a_closed_part_are_left_out_a_book_is_pinched_on_its_cover(tmp_path):
    """A book: a closed cover (150 x 220 x 30 mm) and 32 page sheets inside it, turned and moved off
    the origin. The pages are removed (a hand touches the cover only) and pinches are found across
    the cover; a sheet beside the cover, not inside it, stays."""
    from scipy.spatial.transform import Rotation

    from pinchmatch import PinchSettings, analyze_object, candidate_poses

    cover = trimesh.creation.box(extents=(150, 220, 30))
    pages = []
    for k in range(32):
        page = trimesh.creation.box(extents=(140, 210, 0.5))
        page.apply_translation([0, 0, -12 + k * 0.75])
        pages.append(page)
    loose = trimesh.creation.box(extents=(40, 40, 4))
    loose.apply_translation([120, 0, 0])
    book = trimesh.util.concatenate([cover, *pages, loose])
    M = np.eye(4)
    M[:3, :3] = Rotation.from_euler("xyz", [20, -35, 50], degrees=True).as_matrix()
    M[:3, 3] = [300, -120, 45]
    book.apply_transform(M)
    book.export(tmp_path / "book.stl")
    loaded = load_mesh(tmp_path / "book.stl")
    assert any("32 part(s) lying inside another" in r for r in loaded.repairs)
    assert len(loaded.mesh.faces) == 24  # the cover's 12 and the loose sheet's 12
    obj = analyze_object(tmp_path / "book.stl")
    poses = candidate_poses(obj, settings=PinchSettings(count=60, seed=2))
    widths = np.linalg.norm(poses.pinches.points[:, 1] - poses.pinches.points[:, 0], axis=1)
    assert len(poses) == 60 and (widths > 3.0).all()  # never a page's half millimetre
    # across the cover (30 mm, longer where the pinch line leans within the friction cone), or the
    # loose sheet
    assert ((widths > 29.9) & (widths < 36.0)).sum() > 30 and (
        (widths > 3.9) & (widths < 5.0)).any()


@pytest.mark.parametrize("wound", ["outward", "inward"])
def test_a_book_in_an_open_cover_is_pinched_across_its_cover(tmp_path, wound):
    """A book as game assets model one: the cover three open sheets (front, spine, back; no
    thickness) around 32 page sheets, the cover's faces pointing out of the book or into it, turned
    and moved off the origin. The pages are removed (inside the open cover by the generalized
    winding number), a cover wound inward is turned to face out, and pinches are found across the
    cover; a lone sheet is left facing as it was."""
    from scipy.spatial.transform import Rotation

    from pinchmatch import PinchSettings, analyze_object, candidate_poses

    W, H, T = 150.0, 220.0, 30.0
    # front, spine, back
    corners = [(W / 2, T / 2), (-W / 2, T / 2), (-W / 2, -T / 2), (W / 2, -T / 2)]
    vertices = [[x, y, z] for y in (-H / 2, H / 2) for x, z in corners]
    faces = [f for k in range(3) for f in ([k, k + 1, 5 + k], [k, 5 + k, 4 + k])]
    # wound into the book
    cover = trimesh.Trimesh(vertices, faces, process=False).subdivide().subdivide()
    if wound == "outward":
        cover.invert()
    pages = []
    for k in range(32):
        page = trimesh.creation.box(extents=(140, 210, 0.5))
        page.apply_translation([0, 0, -12 + k * 0.75])
        pages.append(page)
    book = trimesh.util.concatenate([cover, *pages])
    M = np.eye(4)
    M[:3, :3] = Rotation.from_euler("xyz", [-25, 40, 110], degrees=True).as_matrix()
    M[:3, 3] = [-80, 310, 25]
    book.apply_transform(M)
    book.export(tmp_path / "book.stl")
    loaded = load_mesh(tmp_path / "book.stl")
    assert any("32 part(s) lying inside another" in r for r in loaded.repairs), loaded.repairs
    assert any("face outward" in r for r in loaded.repairs) == (wound == "inward"), loaded.repairs
    # the front sheet's faces
    front = loaded.mesh.triangles_center @ M[:3, 2] - M[:3, 3] @ M[:3, 2] > T / 2 - 1e-6
    assert (loaded.mesh.face_normals[front] @ M[:3, 2] > 0.99).all()  # facing out of the book
    poses = candidate_poses(analyze_object(tmp_path / "book.stl"),
                            settings=PinchSettings(count=40, seed=3))
    widths = np.linalg.norm(poses.pinches.points[:, 1] - poses.pinches.points[:, 0], axis=1)
    assert len(poses) == 40 and ((widths > 29.9) & (widths < 36.0)).all(), widths
    tile = trimesh.creation.cylinder(radius=30.0, height=80.0, sections=48)
    # half a tube
    tile.update_faces((np.abs(tile.face_normals[:, 2]) < 0.5) & (tile.triangles_center[:, 1] > 0))
    for turned in (False, True):
        # a lone sheet, facing either way: its two sides are alike, it stays as it is
        sheet = tile.copy()
        if turned:
            sheet.invert()
        sheet.apply_transform(M)
        sheet.export(tmp_path / "sheet.stl")
        lone = load_mesh(tmp_path / "sheet.stl")
        assert not any("face outward" in r for r in lone.repairs), lone.repairs
        np.testing.assert_allclose(lone.mesh.face_normals.mean(axis=0),
                                   sheet.face_normals.mean(axis=0), atol=1e-6)
