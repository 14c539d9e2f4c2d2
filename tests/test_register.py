import numpy as np
import pytest

from pinchmatch.match.register import register_pose

from conftest import random_rigid


def pose(seed):
    rng = np.random.default_rng(seed)
    points = rng.uniform(-30, 30, (2, 3))
    normals = rng.normal(size=(2, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    com = rng.uniform(-10, 10, 3)
    axis = rng.normal(size=3)
    return points, normals, com, axis / np.linalg.norm(axis)


@pytest.mark.parametrize("seed", range(5))
@pytest.mark.parametrize("swapped", [False, True])
def test_a_moved_copy_registers_back_onto_the_original(seed, swapped):
    points, normals, com, axis = pose(seed)
    R, t = random_rigid(seed + 100)
    v_points, v_normals = points @ R.T + t, normals @ R.T
    if swapped:
        v_points, v_normals = v_points[::-1], v_normals[::-1]
    T = register_pose(points, normals, v_points, v_normals, swapped=swapped,
                      tangible_com=com, virtual_com=R @ com + t, tangible_axis=axis,
                      virtual_axis=R @ axis)
    assert np.linalg.det(T[:3, :3]) == pytest.approx(1.0)
    np.testing.assert_allclose(T[:3, :3], R.T, atol=1e-9)
    np.testing.assert_allclose(T[:3, 3], -R.T @ t, atol=1e-7)


def test_midpoints_meet_and_lines_are_parallel_for_different_poses():
    tp, tn, tc, ta = pose(1)
    vp, vn, vc, va = pose(2)
    T = register_pose(tp, tn, vp, vn, swapped=False, tangible_com=tc, virtual_com=vc,
                      tangible_axis=ta, virtual_axis=va)
    moved = vp @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(moved.mean(axis=0), tp.mean(axis=0), atol=1e-9)
    u_t = (tp[1] - tp[0]) / np.linalg.norm(tp[1] - tp[0])
    u_v = (moved[1] - moved[0]) / np.linalg.norm(moved[1] - moved[0])
    np.testing.assert_allclose(u_v, u_t, atol=1e-9)


def test_the_smallest_rotation_between_opposite_vectors_is_a_half_turn():
    from pinchmatch.mesh.frames import rotations_between

    a = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.6, 0.8, 0.0]])
    R = rotations_between(a, -a)
    for Rk, ak in zip(R, a):
        np.testing.assert_allclose(Rk @ ak, -ak, atol=1e-12)
        np.testing.assert_allclose(Rk @ Rk.T, np.eye(3), atol=1e-12)
        assert np.linalg.det(Rk) == pytest.approx(1.0)
        assert np.trace(Rk) == pytest.approx(-1.0)  # a half turn: 1 + 2 cos(180 deg)


def test_register_pose_takes_plain_lists():
    args = dict(swapped=False, tangible_com=[0.0, 0.0, 0.0], virtual_com=[0.0, 0.0, 0.0],
                tangible_axis=[0.0, 0.0, 1.0], virtual_axis=[0.0, 0.0, 1.0])
    T = register_pose([[-10.0, 0.0, 0.0], [10.0, 0.0, 0.0]], [[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]],
                      [[0.0, -10.0, 5.0], [0.0, 10.0, 5.0]], [[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]],
                      **args)
    np.testing.assert_allclose(T[:3, :3] @ [0.0, -10.0, 5.0] + T[:3, 3], [-10.0, 0.0, 0.0],
                               atol=1e-9)


@pytest.mark.parametrize("side", ["virtual", "tangible"])
def test_a_normal_within_five_degrees_of_the_line_has_no_say_in_the_roll(side):
    """One object's normals 3° off the pinch line (noise, across it +Y), the other's 30° off (+Z):
    the first say nothing, so the masses and the axes, which agree on no roll, decide it exactly."""
    points = np.array([[-10.0, 0.0, 0.0], [10.0, 0.0, 0.0]])

    def normals(deg, across):
        s, c = np.sin(np.radians(deg)), np.cos(np.radians(deg))
        return np.array([[-c, 0.0, 0.0], [c, 0.0, 0.0]]) + s * np.asarray(across)

    near, far = normals(3.0, [0.0, 1.0, 0.0]), normals(30.0, [0.0, 0.0, 1.0])
    t_normals, v_normals = (far, near) if side == "virtual" else (near, far)
    com, axis = np.array([0.0, -30.0, 0.0]), np.array([0.0, 0.0, 1.0])
    T = register_pose(points, t_normals, points, v_normals, swapped=False, tangible_com=com,
                      virtual_com=com, tangible_axis=axis, virtual_axis=axis)
    np.testing.assert_allclose(T[:3, :3], np.eye(3), atol=1e-12)
    tilted = register_pose(points, t_normals, points, normals(6.0, [0.0, 1.0, 0.0]) if side
                           == "virtual" else v_normals,
                           swapped=False, tangible_com=com, virtual_com=com, tangible_axis=axis,
                           virtual_axis=axis)
    if side == "virtual":  # at 6° the normal has its say: the roll turns towards it
        assert abs(tilted[2, 1]) > 1e-3


@pytest.mark.parametrize("seed", [2, 9])
def test_three_contacts_register_back_onto_the_original_at_a_random_place(seed):
    """A tripod's contacts and normals, turned and moved at random: the fit undoes the motion
    exactly; with the contacts perturbed, the placed contacts stay within the perturbation and the
    fit is a rotation."""
    from pinchmatch.match.register import NORMAL_LEVER_MM, register_contacts

    rng = np.random.default_rng(seed)
    p = np.array([[-25.0, 3.0, 1.0], [22.0, -11.0, 4.0],
                  [24.0, 12.0, -2.0]]) + rng.normal(size=3) * 40.0
    n = np.array([[-1.0, 0.1, 0.0], [0.9, -0.3, 0.1], [0.9, 0.4, -0.1]])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    R, t = random_rigid(seed)
    vp, vn = p @ R.T + t, n @ R.T
    T = register_contacts(p[None], n[None], vp[None], vn[None])[0]
    assert T.shape == (4, 4)
    np.testing.assert_array_equal(T[3], [0.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(vp @ T[:3, :3].T + T[:3, 3], p, atol=1e-9)
    np.testing.assert_allclose(T[:3, :3], R.T, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(T[:3, :3]), 1.0, atol=1e-12)
    # the centroids meet, whatever the noise; the normals weigh as points NORMAL_LEVER_MM out along
    # them
    noisy = vp + rng.normal(size=(3, 3)) * 0.5
    T = register_contacts(p[None], n[None], noisy[None], vn[None])[0]
    placed = noisy @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(placed.mean(axis=0), p.mean(axis=0), atol=1e-9)
    assert np.linalg.norm(placed - p, axis=1).max() < 2.0
    assert NORMAL_LEVER_MM == 8.0
    # a virtual normal turned 40 degrees pulls the fit away from the contacts' own (a normal
    # reversed exactly would not: it adds no torque at that rotation)
    from scipy.spatial.transform import Rotation

    axis = np.cross(vn[0], [0.0, 0.0, 1.0])
    tilted = vn.copy()
    tilted[0] = Rotation.from_rotvec(np.radians(40.0) * axis / np.linalg.norm(axis)).apply(vn[0])
    turned = register_contacts(p[None], n[None], vp[None], tilted[None])[0]
    assert np.abs(turned[:3, :3] - R.T).max() > 1e-3
