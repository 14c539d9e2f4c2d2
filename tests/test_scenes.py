import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from conftest import finger_axes
from pinchmatch.export.scenes import CONE_HEIGHT_MM, gltf_rotation, write_scenes


#: glTF is +Y up: x stays, z becomes y, y becomes -z
Z_UP_TO_GLTF = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@pytest.fixture(scope="module")
def written(tmp_path_factory, demo):
    return demo.study, write_scenes(demo.study.scene, tmp_path_factory.mktemp("scenes"))


def test_z_up_becomes_gltf_y_up():
    np.testing.assert_allclose(gltf_rotation(np.array([0.0, 0.0, 1.0])), Z_UP_TO_GLTF, atol=1e-12)


def test_glb_round_trip_gives_named_nodes_transforms_and_extras(written):
    study, paths = written
    assert [p.name for p in paths] == [f"{p.stem}.glb" for p in paths] and len(paths) == 6
    Q = gltf_rotation(np.array([0.0, 0.0, 1.0]))
    for vm, path in zip(study.scene.matches, paths):
        scene = trimesh.load(path)
        assert set(scene.graph.nodes_geometry) == {"tangible", "virtual", "cone_p1", "cone_p2",
                                                   "finger_p1", "finger_p2"}
        # each finger: a capsule 45 mm long plus its two 8 mm caps, from its fingertip along its own
        # axis, the approach leaned 15 deg away from the other finger
        T = study.scene.tangibles[vm.best.tangible]
        h = T.pinches.approach[vm.best.t_pose]
        p = T.pinches.points[vm.best.t_pose]
        u = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
        axes = finger_axes(h[None], u[None], 15.0, 2)[0]
        for k in range(2):
            finger = scene.geometry[f"finger_p{k + 1}"]
            tip = (p[k] + 8.0 * T.pinches.normals[vm.best.t_pose, k]) @ Q.T / 1000.0
            along = (finger.vertices - tip) @ (Q @ axes[k])
            assert (along.min() == pytest.approx(-0.008, abs=2e-4) and along.max()
                    == pytest.approx(0.053, abs=2e-4))
            extras = scene.graph.transforms.edge_data[("world", f"finger_p{k + 1}")]["metadata"]
            np.testing.assert_allclose(extras["pinchmatch:approach"], h, atol=1e-9)
            np.testing.assert_allclose(extras["pinchmatch:direction"], axes[k], atol=1e-9)
        assert scene.metadata["pinchmatch:units"] == "m" and scene.metadata["pinchmatch:up"] == "+y"
        # the tangible, in metres and +Y up: 120 mm tall along Y
        tangible = scene.geometry["tangible"]
        assert tangible.bounds[:, 1] == pytest.approx([0.0, 0.12], abs=1e-6)
        # the virtual node places the virtual mesh where the registration puts it, in +Y-up metres:
        # its vertices' centroid (affine maps keep centroids), against the file's in mm, moved by
        # hand
        matrix, _ = scene.graph["virtual"]
        X = vm.best.transform
        local = scene.geometry["virtual"].vertices.mean(axis=0)
        placed = matrix[:3, :3] @ local + matrix[:3, 3]
        file_mm = study.scene.virtuals[vm.virtual].obj.loaded.mesh.vertices.mean(axis=0)
        np.testing.assert_allclose(placed, Z_UP_TO_GLTF @ (X[:3, :3] @ file_mm + X[:3, 3]) / 1000.0,
                                   atol=1e-6)
        extras = scene.graph.transforms.edge_data[("world", "virtual")]["metadata"]
        assert extras["pinchmatch:cost"] == pytest.approx(vm.best.cost)
        assert extras["pinchmatch:flipped"] == vm.best.flipped
        np.testing.assert_allclose(np.reshape(extras["pinchmatch:transform_virtual_to_tangible_mm"],
                                              (4, 4)), X)
        # each cone's tip sits on its contact, its body outside along the pinch line
        p = study.tangible.pinches.points[vm.best.t_pose]
        for k in range(2):
            cone = scene.geometry[f"cone_p{k + 1}"]
            tip = Q @ p[k] / 1000.0
            assert np.linalg.norm(cone.vertices - tip, axis=1).min() < 1e-6
            centre = cone.vertices.mean(axis=0) * 1000.0 @ Q  # back to the tangible's mm frame
            outward = (p[k] - p[1 - k]) / np.linalg.norm(p[k] - p[1 - k])
            assert (centre - p[k]) @ outward > 0.2 * CONE_HEIGHT_MM


def test_scene_extras_map_the_virtual_contacts_into_the_scene(written):
    study, paths = written
    for vm, path in zip(study.scene.matches, paths):
        scene = trimesh.load(path)
        C = np.reshape(scene.metadata["pinchmatch:file_mm_to_gltf_m"], (4, 4))
        extras = scene.graph.transforms.edge_data[("world", "virtual")]["metadata"]
        q = np.reshape(extras["pinchmatch:virtual_contacts_mm"], (2, 3))
        # registered, the virtual contacts lie on the tangible's pinch line, around the same
        # midpoint
        matrix, _ = scene.graph["virtual"]
        q_scene = (np.c_[q, np.ones(2)] @ C.T) @ matrix.T
        p = study.tangible.pinches.points[vm.best.t_pose]
        p_scene = np.c_[p, np.ones(2)] @ C.T
        np.testing.assert_allclose(q_scene.mean(axis=0), p_scene.mean(axis=0), atol=1e-6)
        u = (p_scene[1, :3] - p_scene[0, :3]) / np.linalg.norm(p_scene[1, :3] - p_scene[0, :3])
        assert (q_scene[1, :3] - q_scene[0, :3]) @ u > 0  # p1 meets p1


def test_the_engine_guide_recipes_give_the_scene_placement(written):
    """docs/engines.md: B·T·B⁻¹ with B = file_mm_to_gltf_m is the virtual node's matrix
    (three.js), and Unity's mirror S = diag(-1, 1, 1) turns it into a rotation whose quaternion is
    (x, -y, -z, w)."""
    from scipy.spatial.transform import Rotation

    study, paths = written
    for vm, path in zip(study.scene.matches, paths):
        scene = trimesh.load(path)
        B = np.reshape(scene.metadata["pinchmatch:file_mm_to_gltf_m"], (4, 4))
        node, _ = scene.graph["virtual"]
        # GLB: float32
        np.testing.assert_allclose(B @ vm.best.transform @ np.linalg.inv(B), node, atol=1e-6)
        S = np.diag([-1.0, 1.0, 1.0])
        unity = S @ node[:3, :3] @ S
        assert np.linalg.det(unity) == pytest.approx(1.0)
        x, y, z, w = Rotation.from_matrix(node[:3, :3]).as_quat()
        np.testing.assert_allclose(Rotation.from_quat([x, -y, -z, w]).as_matrix(), unity, atol=1e-6)


BLENDER = shutil.which("blender")


@pytest.mark.skipif(BLENDER is None and not os.environ.get("CI"),
                    reason="Blender not installed (apt-get install blender python3-numpy); .ci/run "
                           "installs it")
def test_scene_opens_in_blender(written):
    """Blender's own glTF importer: Z-up metres, so the node matrix comes back as the mm transform /
    1000."""
    assert BLENDER is not None, ".ci/run installs Debian's blender"
    study, paths = written
    vm, path = study.scene.matches[3], paths[3]
    script = Path(__file__).parents[1] / "tools" / "blender_import_check.py"
    # Blender embeds the system's Python: keep a virtualenv's or pyenv's python3 off its PATH
    env = dict(os.environ, PATH=os.pathsep.join(["/usr/bin", "/bin", str(Path(BLENDER).parent)]))
    env.pop("PYTHONHOME", None)
    env.pop("PYTHONPATH", None)
    run = subprocess.run([BLENDER, "-b", "--factory-startup", "--python", str(script), "--",
                          str(path)],
                         capture_output=True, text=True, timeout=300, env=env)
    line = next((x for x in run.stdout.splitlines() if x.startswith("RESULT ")), None)
    assert line is not None, run.stdout[-2000:] + run.stderr[-2000:]
    objects = json.loads(line[len("RESULT "):])
    assert set(objects) == {"tangible", "virtual", "cone_p1", "cone_p2", "finger_p1", "finger_p2"}
    assert objects["tangible"]["dimensions"] == pytest.approx([0.06, 0.06, 0.12], abs=1e-4)
    X = vm.best.transform
    world = np.array(objects["virtual"]["matrix_world"])
    # the study files are Z-up, like Blender
    np.testing.assert_allclose(world[:3, :3], X[:3, :3], atol=1e-5)
    np.testing.assert_allclose(world[:3, 3], X[:3, 3] / 1000.0, atol=1e-6)
    extras = objects["virtual"]["extras"]
    assert (extras["pinchmatch:cost"] == pytest.approx(vm.best.cost)
            and bool(extras["pinchmatch:flipped"]) == vm.best.flipped)
