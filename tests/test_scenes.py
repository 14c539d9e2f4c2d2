import numpy as np
import pytest
import trimesh

from pinchmatch.scenes import CONE_HEIGHT_MM, gltf_rotation, write_scenes
from pinchmatch.study import run_study


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scenes")
    study = run_study(folder / "objects")
    return study, write_scenes(study.scene, folder / "scenes")


def test_z_up_becomes_gltf_y_up():
    Q = gltf_rotation(np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(Q @ [0, 0, 1], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(Q @ [1, 0, 0], [1, 0, 0], atol=1e-12)
    assert np.linalg.det(Q) == pytest.approx(1.0)


def test_glb_round_trip_gives_named_nodes_transforms_and_extras(written):
    study, paths = written
    assert [p.name for p in paths] == [f"{p.stem}.glb" for p in paths] and len(paths) == 6
    Q = gltf_rotation(np.array([0.0, 0.0, 1.0]))
    for vm, path in zip(study.scene.matches, paths):
        scene = trimesh.load(path)
        assert set(scene.graph.nodes_geometry) == {"tangible", "virtual", "cone_p1", "cone_p2"}
        assert scene.metadata["pinchmatch:units"] == "m" and scene.metadata["pinchmatch:up"] == "+y"
        # the tangible, in metres and +Y up: 120 mm tall along Y
        tangible = scene.geometry["tangible"]
        assert tangible.bounds[:, 1] == pytest.approx([0.0, 0.12], abs=1e-6)
        # the virtual node's matrix is the registration, converted
        matrix, _ = scene.graph["virtual"]
        X = vm.best.transform
        np.testing.assert_allclose(matrix[:3, :3], Q @ X[:3, :3] @ Q.T, atol=1e-6)
        np.testing.assert_allclose(matrix[:3, 3], Q @ X[:3, 3] / 1000.0, atol=1e-6)
        extras = scene.graph.transforms.edge_data[("world", "virtual")]["metadata"]
        assert extras["pinchmatch:cost"] == pytest.approx(vm.best.cost)
        assert extras["pinchmatch:flipped"] == vm.best.flipped
        np.testing.assert_allclose(np.reshape(extras["pinchmatch:transform_virtual_to_tangible_mm"], (4, 4)), X)
        # each cone's tip sits on its contact, its body outside along the pinch line
        p = study.tangible.pinches.points[vm.best.t_pose]
        for k in range(2):
            cone = scene.geometry[f"cone_p{k + 1}"]
            tip = Q @ p[k] / 1000.0
            assert np.linalg.norm(cone.vertices - tip, axis=1).min() < 1e-6
            centre = cone.vertices.mean(axis=0) * 1000.0 @ Q  # back to the tangible's mm frame
            outward = (p[k] - p[1 - k]) / np.linalg.norm(p[k] - p[1 - k])
            assert (centre - p[k]) @ outward > 0.2 * CONE_HEIGHT_MM
