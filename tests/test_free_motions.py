"""The motions a pose's overlap leaves free (o3d_spectral.evidence.free_motions): exact cases, in
any frame and any units."""

import numpy as np
import pytest
from scipy.spatial import cKDTree

from o3d_spectral.evidence.free_motions import FreeMotion, free_motions, unresisted_motions
from o3d_spectral.spectra import so3
from o3d_spectral.synthetic.sampling import rigid

VOXEL = 0.008
SPACING = 0.004  # half a voxel between samples


def grid(a: tuple[float, float], b: tuple[float, float]) -> np.ndarray:
    """Even samples (K, 2) of the rectangle ``a`` x ``b`` at :data:`SPACING`."""
    u = np.arange(a[0], a[1] + 1e-12, SPACING)
    v = np.arange(b[0], b[1] + 1e-12, SPACING)
    return np.stack(np.meshgrid(u, v, indexing="ij"), axis=-1).reshape(-1, 2)


def band(radius: float, degrees: tuple[float, float], height: float):
    """The side of a cylinder about z, ``degrees`` of it, ``height`` tall, and its
    outward normals."""
    uv = grid((np.deg2rad(degrees[0]) * radius, np.deg2rad(degrees[1]) * radius),
              (-height / 2, height / 2))
    angle = uv[:, 0] / radius
    normals = np.c_[np.cos(angle), np.sin(angle), np.zeros(len(uv))]
    return np.c_[radius * normals[:, :2], uv[:, 1]], normals


def lid(radius: float, z: float):
    """A disc of ``radius`` about z at height ``z``, its normals up."""
    xy = grid((-radius, radius), (-radius, radius))
    xy = xy[np.hypot(xy[:, 0], xy[:, 1]) <= radius]
    return np.c_[xy, np.full(len(xy), z)], np.tile([0.0, 0.0, 1.0], (len(xy), 1))


def corner(side: float):
    """Three faces of a box meeting at the origin, ``side`` wide, with their normals."""
    face = grid((0.0, side), (0.0, side))
    faces, normals = [], []
    for k in range(3):
        points = np.insert(face, k, 0.0, axis=1)
        faces.append(points)
        normals.append(np.tile(np.eye(3)[k], (len(points), 1)))
    return np.concatenate(faces), np.concatenate(normals)


def joined(*parts):
    return (np.concatenate([p for p, _ in parts]), np.concatenate([n for _, n in parts]))


IDENTITY = np.eye(4)


def found(source, target, motion=IDENTITY, scale=1.0, whole=None):
    """:func:`free_motions` of ``source`` on ``target`` (points, normals each), both
    moved by ``motion`` and scaled by ``scale`` with the voxel."""
    def moved(cloud):
        return scale * (cloud[0] @ motion[:3, :3].T + motion[:3, 3]), cloud[1] @ motion[:3, :3].T
    points, normals = moved(source)
    target_points, target_normals = moved(target)
    whole_points, whole_normals = moved(source if whole is None else whole)
    tree = cKDTree(target_points)
    distance, _ = tree.query(points, distance_upper_bound=scale * VOXEL)
    return free_motions(points, normals, np.isfinite(distance), target_points,
                        target_normals, tree, scale * VOXEL, whole_points, whole_normals)


FRAMES = [(np.eye(4), 1.0),
          (rigid(so3.exp(np.array([0.7, -0.4, 1.1])), np.array([1.5, -0.3, 2.0])), 1.0),
          (rigid(so3.exp(np.array([-1.2, 0.2, 0.5])), np.array([-0.2, 0.4, 0.1])), 1000.0)]


def kinds(motions: tuple[FreeMotion, ...]) -> list[str]:
    return sorted(m.kind for m in motions)


@pytest.mark.parametrize(("motion", "scale"), FRAMES)
def test_a_lidded_cylinder_patch_on_a_wider_one_leaves_one_turn_about_its_axis(motion, scale):
    """A can's side, 60 degrees of it, and its lid, on 180 degrees of the same side and
    the lid: the lid holds the slide along the axis, the side every motion but the turn
    about it, which goes all the way round (the lid, most of the points, stays on the
    lid; the side leaves the target's side for where the target shows nothing). A
    symmetry of the source: it is a patch of a surface of revolution."""
    source = joined(band(0.05, (60.0, 120.0), 0.08), lid(0.05, 0.04))
    target = joined(band(0.05, (0.0, 180.0), 0.08), lid(0.05, 0.04))
    motions = found(source, target, motion, scale)
    assert kinds(motions) == ["turn"]
    turn = motions[0]
    axis, point = motion[:3, 2], scale * motion[:3, 3]
    assert abs(turn.axis @ axis) == pytest.approx(1.0, abs=1e-6)
    off = turn.point - point
    assert np.linalg.norm(off - (off @ axis) * axis) < 1e-6 * scale
    assert turn.reach == (-180.0, 180.0)
    assert turn.symmetric


@pytest.mark.parametrize(("motion", "scale"), FRAMES)
def test_a_bare_cylinder_band_leaves_its_turn_and_the_slide_along_its_axis(motion, scale):
    """Without the lid nothing holds the slide along the axis either: a band, 60 degrees
    of the side 6 cm tall, on 180 degrees 16 cm tall leaves that slide and the turn, each
    as far as half the band stays on the target: 5 + 3 cm, 60 + 30 degrees either way
    (and up to a voxel and a step more: a point is over the target's surface within a
    voxel of its edge)."""
    source = band(0.05, (60.0, 120.0), 0.06)
    target = band(0.05, (0.0, 180.0), 0.16)
    motions = found(source, target, motion, scale)
    assert kinds(motions) == ["slide", "turn"]
    for m in motions:
        assert abs(m.axis @ motion[:3, 2]) == pytest.approx(1.0, abs=1e-6)
        far, slack = (0.08 * scale, 2 * VOXEL * scale) if m.kind == "slide" else (90.0, 15.0)
        low, high = m.reach
        assert far <= -low <= far + slack and far <= high <= far + slack
        assert m.symmetric


@pytest.mark.parametrize(("motion", "scale"), FRAMES)
def test_a_plane_on_a_wider_plane_leaves_two_slides_and_a_turn(motion, scale):
    """A disc 10 cm wide on one 30 cm wide in the same plane: the slides across it and the
    turn about its normal are free (a plane is its own symmetry along them); the slides go
    on while about half the small disc stays on the wider one (its centre at the other's
    edge, 15 cm), the turn all the way round."""
    motions = found(lid(0.05, 0.0), lid(0.15, 0.0), motion, scale)
    assert kinds(motions) == ["slide", "slide", "turn"]
    normal = motion[:3, 2]
    for m in motions:
        if m.kind == "slide":
            assert abs(m.axis @ normal) < 1e-6
            low, high = m.reach
            assert 0.14 * scale <= -low <= (0.15 + 2 * VOXEL) * scale
            assert 0.14 * scale <= high <= (0.15 + 2 * VOXEL) * scale
        else:
            assert abs(m.axis @ normal) == pytest.approx(1.0, abs=1e-6)
            assert m.reach == (-180.0, 180.0)
        assert m.symmetric


@pytest.mark.parametrize(("motion", "scale"), FRAMES)
def test_a_box_corner_leaves_nothing_free(motion, scale):
    """Three faces of a box on a larger corner: every motion is held."""
    assert found(corner(0.08), corner(0.12), motion, scale) == ()


def test_a_free_motion_that_the_whole_source_resists_is_not_its_symmetry():
    """The same lidded patch, the source also showing a tab beside the side that the
    target does not show: the tab is no inlier, the turn stays free, but the whole source
    resists it: not a symmetry, the data do not fix the pose along it."""
    patch = joined(band(0.05, (60.0, 120.0), 0.08), lid(0.05, 0.04))
    xz = grid((0.06, 0.09), (-0.02, 0.02))  # radially out of the side, in y = 0
    tab_points = np.c_[xz[:, 0], np.zeros(len(xz)), xz[:, 1]]
    turned = so3.exp(np.deg2rad(90.0) * np.array([0.0, 0.0, 1.0]))
    tab = (tab_points @ turned.T, np.tile(turned @ np.array([0.0, 1.0, 0.0]), (len(tab_points), 1)))
    target = joined(band(0.05, (0.0, 180.0), 0.08), lid(0.05, 0.04))
    motions = found(patch, target, whole=joined(patch, tab))
    assert kinds(motions) == ["turn"] and not motions[0].symmetric


def test_unresisted_motions_of_a_sphere_are_three_turns_about_its_centre():
    """Points on a sphere resist no turn about its centre and every slide."""
    rng = np.random.default_rng(0)
    normals = rng.normal(size=(3000, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    centre = np.array([0.3, -0.1, 0.2])
    motions = unresisted_motions(centre + 0.05 * normals, normals)
    assert [kind for kind, _, _ in motions] == ["turn"] * 3
    for _, axis, point in motions:
        off = point - centre
        assert np.linalg.norm(off - (off @ axis) * axis) < 1e-9


def test_a_free_motion_moves_by_what_it_says_and_follows_a_shift_of_frame():
    """``transformation(amount)`` turns about its line by degrees (points on it stay),
    slides by metres; ``shifted`` moves its point, nothing else."""
    turn = FreeMotion("turn", np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]),
                      (-10.0, 30.0), False)
    M = turn.transformation(90.0)
    assert np.allclose(M @ [1.0, 0.0, 5.0, 1.0], [1.0, 0.0, 5.0, 1.0])
    assert np.allclose(M @ [2.0, 0.0, 0.0, 1.0], [1.0, 1.0, 0.0, 1.0])
    assert turn.extent == 40.0
    slide = FreeMotion("slide", np.array([0.0, 1.0, 0.0]), np.zeros(3), (-0.1, 0.2), True)
    assert np.allclose(slide.transformation(0.5)[:3, 3], [0.0, 0.5, 0.0])
    moved = turn.shifted(np.array([0.0, 2.0, 0.0]))
    assert np.allclose(moved.point, [1.0, 2.0, 0.0]) and moved.reach == (-10.0, 30.0)



def test_the_global_call_reports_a_cans_turn_as_a_symmetry_in_the_callers_frame():
    """Two views of a can 90 degrees apart: the result holds one free turn, a symmetry of
    the source; the same clouds 50 m away (registered in a frame centred on the target)
    give the same axis, its point moved with them."""
    import copy

    import o3d_spectral
    from o3d_spectral.synthetic.turntable import turntable_pair

    pair = turntable_pair("master_chef_can", 90, 30, np.random.default_rng(20_005))
    near = o3d_spectral.registration_spectral_global(pair.source, pair.target, VOXEL)
    shift = np.array([50.0, -20.0, 10.0])
    far_source, far_target = (copy.deepcopy(c).translate(shift) for c in (pair.source,
                                                                          pair.target))
    far = o3d_spectral.registration_spectral_global(far_source, far_target, VOXEL)
    assert [m.kind for m in near.free_motions] == ["turn"] and near.free_motions[0].symmetric
    assert [m.kind for m in far.free_motions] == ["turn"]
    a, b = near.free_motions[0], far.free_motions[0]
    assert abs(a.axis @ b.axis) == pytest.approx(1.0, abs=1e-3)
    off = b.point - (a.point + shift)
    assert np.linalg.norm(off - (off @ a.axis) * a.axis) < 0.002
