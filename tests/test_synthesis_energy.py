"""Grasp-synthesis energy terms (3.1.4, eqs. 4-14) and the torch SDF vs independent references."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
import trimesh
from scipy.optimize import minimize_scalar

from graspstab.objects.sdf import SDFGrid, exact_signed_distance
from graspstab.synthesis.energy import (
    WEIGHT_KEYS,
    PenetrationPoints,
    e_dis,
    e_fc,
    e_hpen,
    e_joint,
    e_pen,
    e_pen_dense,
    e_spen,
    penetration_depths,
    point_segment_distance,
    segment_segment_distance,
    total_energy,
)
from graspstab.synthesis.sdf_torch import TorchSDF

F64 = torch.float64


# ---------------------------------------------------------------------------------------------
# independent numpy references (written without looking at the torch code paths)


def ref_point_segment(q: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance from q to segment a-b, by projection."""
    d = b - a
    dd = float(d @ d)
    t = 0.0 if dd == 0 else min(1.0, max(0.0, float((q - a) @ d) / dd))
    return float(np.linalg.norm(q - (a + t * d)))


def ref_box_sdf(q: np.ndarray, center: np.ndarray, rot: np.ndarray, half: np.ndarray) -> float:
    """Signed distance to an oriented box (columns of rot = box axes), the textbook formula."""
    local = rot.T @ (q - center)
    k = np.abs(local) - half
    return float(np.linalg.norm(np.maximum(k, 0.0)) + min(k.max(), 0.0))


def ref_segment_segment(a0, a1, b0, b1) -> float:
    """Minimise the (convex) distance from a point on segment A to segment B over A's parameter."""
    res = minimize_scalar(
        lambda s: ref_point_segment(a0 + s * (a1 - a0), b0, b1),
        bounds=(0.0, 1.0),
        method="bounded",
        options={"xatol": 1e-12},
    )
    ends = [ref_point_segment(a0, b0, b1), ref_point_segment(a1, b0, b1)]
    return min([float(res.fun), *ends])


def ref_penetration(points, p0, p1, radii, center, rot, half) -> np.ndarray:
    """Per grasp and point (B, M): max(-d_H(q), 0) with d_H the min over primitives, by loops."""
    out = np.zeros((len(p0), len(points)))
    for b in range(len(p0)):
        for m, q in enumerate(points):
            sdf = [ref_point_segment(q, p0[b, k], p1[b, k]) - radii[k] for k in range(len(radii))]
            sdf.append(ref_box_sdf(q, center[b], rot[b], half))
            out[b, m] = max(-min(sdf), 0.0)
    return out


def ref_e_pen(*args) -> np.ndarray:
    """Eq. (11): the sum over the object points."""
    return ref_penetration(*args).sum(1)


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """Random proper rotation matrices (n, 3, 3)."""
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    q = q * np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    q[np.linalg.det(q) < 0, :, 0] *= -1
    return q


def t64(x: np.ndarray) -> torch.Tensor:
    return torch.as_tensor(np.asarray(x), dtype=F64)


# ---------------------------------------------------------------------------------------------
# fixtures


@pytest.fixture(scope="module")
def brick_grid(foam_brick_dir: Path) -> SDFGrid:
    return SDFGrid.load(foam_brick_dir / "sdf.npz")


@pytest.fixture(scope="module")
def brick_hull(foam_brick_dir: Path) -> np.ndarray:
    return np.load(foam_brick_dir / "hull_points.npy").astype(np.float64)


# ---------------------------------------------------------------------------------------------
# TorchSDF


def _box_points(grid: SDFGrid, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform(grid.origin - 0.03, grid.upper + 0.03, size=(n, 3))


def test_torch_sdf_equals_sdfgrid_query(foam_brick_dir: Path, brick_grid: SDFGrid) -> None:
    pts = _box_points(brick_grid, 6000, seed=0)
    outside = np.any((pts < brick_grid.origin) | (pts > brick_grid.upper), axis=1)
    assert 500 < outside.sum() < 5500  # both regimes are exercised
    dist, normal = brick_grid.query(pts)

    sdf64 = TorchSDF.load(foam_brick_dir / "sdf.npz", dtype=F64)
    d64, n64 = sdf64.query(t64(pts).reshape(60, 100, 3))  # any leading shape
    assert d64.shape == (60, 100) and n64.shape == (60, 100, 3) and d64.dtype == F64
    np.testing.assert_allclose(d64.reshape(-1).numpy(), dist, rtol=0, atol=1e-9)
    # SDFGrid.query rounds three of its corner differences in float32 (it promotes only c000),
    # which moves its normals by up to ~1e-7; exact agreement is checked on a grid below
    np.testing.assert_allclose(n64.reshape(-1, 3).numpy(), normal, rtol=0, atol=1e-6)

    sdf32 = TorchSDF.from_grid(brick_grid, dtype=torch.float32)
    d32, n32 = sdf32.query(torch.as_tensor(pts, dtype=torch.float32))
    assert d32.dtype == torch.float32
    np.testing.assert_allclose(d32.double().numpy(), dist, rtol=0, atol=1e-5)
    np.testing.assert_allclose(n32.double().numpy(), normal, rtol=0, atol=1e-4)


def test_torch_sdf_float64_bitwise_semantics_on_exact_grid(brick_grid: SDFGrid) -> None:
    # values on a 2^-20 lattice make every float32 difference in SDFGrid.query exact, so the two
    # implementations must agree to rounding in float64, normals and the outside extension included
    values = np.round(brick_grid.values.astype(np.float64) * 2**20) / 2**20
    grid = SDFGrid(values=values.astype(np.float32), origin=brick_grid.origin, spacing=0.0015)
    pts = _box_points(grid, 4000, seed=1)
    pts[:10] = grid.origin + 1e-12  # corner cells and exact node hits
    pts[10:20] = grid.upper
    dist, normal = grid.query(pts)
    d, n = TorchSDF.from_grid(grid, dtype=F64).query(t64(pts))
    np.testing.assert_allclose(d.numpy(), dist, rtol=0, atol=1e-12)
    np.testing.assert_allclose(n.numpy(), normal, rtol=0, atol=1e-9)
    assert np.allclose(np.linalg.norm(n.numpy(), axis=1), 1.0)


def test_depth_sum_equals_e_hpen_of_query(brick_grid: SDFGrid) -> None:
    """The fused, block-culled kernel of E_hpen against the plain sum over a full query."""
    rng = np.random.default_rng(5)
    mid = 0.5 * (brick_grid.origin + brick_grid.upper)
    # half near the object (many inside), half anywhere in and around the grid box
    near = mid + rng.normal(scale=0.02, size=(3000, 3))
    pts = np.concatenate([near, _box_points(brick_grid, 3000, seed=6)]).reshape(20, 300, 3)
    for dtype, tol in ((F64, 1e-12), (torch.float32, 1e-6)):
        sdf = TorchSDF.from_grid(brick_grid, dtype=dtype)
        x = torch.as_tensor(pts, dtype=dtype)
        expected = e_hpen(sdf.query(x)[0])
        got = sdf.depth_sum(x)
        assert got.dtype == dtype and got.shape == (20,)
        assert (expected > 0).all()
        np.testing.assert_allclose(got.double().numpy(), expected.double().numpy(), rtol=tol)
    # the blocks are conservative: no node below a block's minimum, and some blocks are skipped
    sdf = TorchSDF.from_grid(brick_grid, dtype=F64)
    block = sdf.block_min
    values = brick_grid.values
    nx, ny, nz = (n - 1 for n in values.shape)  # cells per axis
    i, j, k = (np.arange(n) // 4 for n in (nx, ny, nz))  # cell -> block
    corner = np.minimum.reduce(
        [values[a : a + nx, b : b + ny, c : c + nz] for a in (0, 1) for b in (0, 1) for c in (0, 1)]
    )
    assert np.all(block[np.ix_(i, j, k)] <= corner)
    assert 0.3 < np.mean(block >= 0) < 1.0


# ---------------------------------------------------------------------------------------------
# E_dis (eq. 5)


def test_e_dis_matches_exact_mesh_distance(foam_brick_dir: Path) -> None:
    mesh = trimesh.load(foam_brick_dir / "mesh.obj", force="mesh", process=False)
    rng = np.random.default_rng(2)
    pts, face = trimesh.sample.sample_surface(mesh, 4 * 120, seed=3)
    pts = pts + mesh.face_normals[face] * rng.uniform(-0.01, 0.01, (len(pts), 1))
    exact = exact_signed_distance(mesh, pts)
    assert (exact < -1e-3).sum() > 50 and (exact > 1e-3).sum() > 50

    sdf = TorchSDF.load(foam_brick_dir / "sdf.npz", dtype=F64)
    dist, _ = sdf.query(t64(pts).reshape(4, 120, 3))
    np.testing.assert_allclose(dist.reshape(-1).numpy(), exact, rtol=0, atol=1e-3)
    energy = e_dis(dist)
    assert energy.shape == (4,)
    np.testing.assert_allclose(energy.numpy(), np.abs(exact).reshape(4, 120).sum(1), atol=0.12)
    np.testing.assert_allclose(energy.numpy(), dist.abs().sum(1).numpy(), rtol=1e-15)


# ---------------------------------------------------------------------------------------------
# E_fc (eqs. 6-10)


def test_e_fc_balanced_configurations_are_zero() -> None:
    a = 0.03
    antipodal_p = [[a, 0, 0], [-a, 0, 0]]
    antipodal_c = [[-1, 0, 0], [1, 0, 0]]
    four_p = [[a, 0, 0], [-a, 0, 0], [0, a, 0], [0, -a, 0]]
    four_c = [[-1, 0, 0], [1, 0, 0], [0, -1, 0], [0, 1, 0]]
    assert float(e_fc(t64([antipodal_p]), t64([antipodal_c]))[0]) == pytest.approx(0, abs=1e-15)
    assert float(e_fc(t64([four_p]), t64([four_c]))[0]) == pytest.approx(0, abs=1e-15)


def test_e_fc_unbalanced_and_hand_computed() -> None:
    a = 0.03
    # balanced forces but a couple: net moment (0, 0, 0.6 a)
    twist = e_fc(t64([[[a, 0, 0], [-a, 0, 0]]]), t64([[[-1, 0.3, 0], [1, -0.3, 0]]]))
    assert float(twist[0]) == pytest.approx((0.6 * a) ** 2, rel=1e-12)
    one_sided = e_fc(t64([[[a, 0, 0], [0, a, 0]]]), t64([[[-1, 0, 0], [-1, 0, 0]]]))
    assert float(one_sided[0]) > 1.0
    # F = (0,1,1), M = (1,0,0)x(0,1,0) + (0,2,0)x(0,0,1) = (0,0,1) + (2,0,0): E = 2 + 5
    value = e_fc(t64([[[1, 0, 0], [0, 2, 0]]]), t64([[[0, 1, 0], [0, 0, 1]]]))
    assert float(value[0]) == pytest.approx(7.0, rel=1e-14)


def test_e_fc_equals_explicit_grasp_matrix() -> None:
    rng = np.random.default_rng(4)
    p, c = rng.normal(size=(3, 10, 3)), rng.normal(size=(3, 10, 3))
    expected = []
    for b in range(3):
        cols = []
        for i in range(10):
            x, y, z = p[b, i]
            skew = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
            cols.append(np.vstack([np.eye(3), skew]))
        g = np.hstack(cols)  # eq. 7, (6, 3N)
        w = g @ c[b].reshape(-1)  # eq. 9
        expected.append(w @ w)  # eq. 10
    np.testing.assert_allclose(e_fc(t64(p), t64(c)).numpy(), expected, rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# E_joint (eq. 14), total energy (eq. 4)


def test_e_joint_linear_violation() -> None:
    lower, upper = -torch.ones(16, dtype=F64), 2 * torch.ones(16, dtype=F64)
    theta = torch.zeros(3, 16, dtype=F64)
    theta[1, 0] = 2.1  # 0.1 above
    theta[1, 5] = -1.2  # 0.2 below
    theta[2, :] = 2.0  # on the limit
    theta[2, 3] = -4.0  # 3 below
    out = e_joint(theta, lower, upper)
    np.testing.assert_allclose(out.numpy(), [0.0, 0.3, 3.0], atol=1e-12)


def test_total_energy_weights_and_keys() -> None:
    terms = {k: torch.full((2,), float(i + 1), dtype=F64) for i, k in enumerate(WEIGHT_KEYS)}
    # eq. 16's weights, then w_hpen
    weights = dict(zip(WEIGHT_KEYS, (100.0, 1.0, 10.0, 100.0, 1000.0, 7.0), strict=True))
    out = total_energy(terms, weights)
    assert out.shape == (2,)
    assert float(out[0]) == 100 * 1 + 1 * 2 + 10 * 3 + 100 * 4 + 1000 * 5 + 7 * 6
    with pytest.raises(KeyError, match="spen"):
        total_energy(terms, {k: v for k, v in weights.items() if k != "spen"})
    with pytest.raises(KeyError, match="bogus"):
        total_energy({**terms, "bogus": terms["dis"]}, weights)


# ---------------------------------------------------------------------------------------------
# segment distance, E_spen (eqs. 12-13)


def _segment_cases(rng: np.random.Generator) -> list[tuple[np.ndarray, ...]]:
    cases = [tuple(rng.normal(scale=0.03, size=(4, 3))) for _ in range(40)]
    x, y = np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    o = np.zeros(3)
    cases += [
        (o, 0.04 * x, 0.01 * y + 0.01 * x, 0.01 * y + 0.06 * x),  # parallel, overlapping
        (o, 0.04 * x, 0.01 * y + 0.05 * x, 0.01 * y + 0.09 * x),  # parallel, disjoint
        (o, 0.04 * x, 0.06 * x, 0.02 * x),  # collinear, reversed, overlapping
        (o, 0.04 * x, 0.05 * x, 0.07 * x),  # collinear, apart
        (o, o, 0.01 * y, 0.01 * y),  # two points
        (0.02 * x + 0.01 * y, 0.02 * x + 0.01 * y, o, 0.04 * x),  # point and segment
        (o, 0.04 * x, 0.02 * x - 0.01 * y, 0.02 * x + 0.01 * y),  # intersecting
        (o, 0.04 * x, 0.02 * x + 0.01 * y, 0.02 * x + 0.01 * y + 1e-9 * x),  # near-degenerate
        (o, 0.04 * x, 0.01 * y, 0.01 * y + 0.04 * x + 1e-7 * y),  # nearly parallel
    ]
    return cases


def test_segment_segment_distance_vs_dense_sampling() -> None:
    cases = _segment_cases(np.random.default_rng(5))
    a0, a1, b0, b1 = (t64(np.stack(col)) for col in zip(*cases, strict=True))
    got = segment_segment_distance(a0, a1, b0, b1).numpy()
    s = np.linspace(0.0, 1.0, 401)[:, None]
    for i, (p0, p1, q0, q1) in enumerate(cases):
        pa = p0 + s * (p1 - p0)
        pb = q0 + s * (q1 - q0)
        sampled = np.linalg.norm(pa[:, None] - pb[None], axis=-1).min()
        step = (np.linalg.norm(p1 - p0) + np.linalg.norm(q1 - q0)) / 400
        assert got[i] <= sampled + 1e-12, i  # never above an actual pair of points
        assert got[i] >= sampled - step / 2 - 1e-12, i
    # parallel / collinear / intersecting cases have exact answers
    np.testing.assert_allclose(
        got[40:47], [0.01, np.hypot(0.01, 0.01), 0, 0.01, 0.01, 0.01, 0], atol=1e-15
    )
    # point-to-segment agrees with the reference helper
    q = t64(np.random.default_rng(6).normal(scale=0.03, size=(50, 3)))
    ref = [ref_point_segment(x, np.zeros(3), np.array([0.03, 0, 0])) for x in q.numpy()]
    got_ps = point_segment_distance(q, t64(np.zeros(3)), t64([0.03, 0, 0]))
    np.testing.assert_allclose(got_ps.numpy(), ref, atol=1e-15)


def test_e_spen_vs_bruteforce() -> None:
    rng = np.random.default_rng(7)
    b, k = 3, 6
    p0 = rng.uniform(-0.03, 0.03, (b, k, 3))
    p1 = p0 + rng.normal(scale=0.02, size=(b, k, 3))
    p1[0, 2] = p0[0, 2]  # a degenerate capsule (a sphere)
    p1[1, 1] = p0[1, 1] + (p1[1, 0] - p0[1, 0])  # parallel to capsule 0
    radii = rng.uniform(0.005, 0.012, k)
    pairs = np.array([(i, j) for i in range(k) for j in range(i + 1, k)])
    expected = np.zeros(b)
    n_pen = 0
    for g in range(b):
        for i, j in pairs:
            s = ref_segment_segment(p0[g, i], p1[g, i], p0[g, j], p1[g, j])
            gap = s - radii[i] - radii[j]  # eq. 12
            expected[g] += max(-gap, 0.0)  # eq. 13
            n_pen += gap < 0
    assert 5 < n_pen < b * len(pairs) - 5  # both colliding and clear pairs
    got = e_spen(t64(p0), t64(p1), t64(radii), torch.as_tensor(pairs))
    np.testing.assert_allclose(got.numpy(), expected, rtol=0, atol=1e-9)


# ---------------------------------------------------------------------------------------------
# E_pen (eq. 11)


def _random_hand(rng: np.random.Generator, b: int, k: int, spread: float = 0.04):
    p0 = rng.uniform(-spread, spread, (b, k, 3))
    p1 = p0 + rng.normal(scale=0.02, size=(b, k, 3))
    radii = rng.uniform(0.005, 0.015, k)
    center = rng.uniform(-spread, spread, (b, 3))
    rot = random_rotations(rng, b)
    half = np.array([0.035, 0.027, 0.006])
    return p0, p1, radii, center, rot, half


def test_e_pen_vs_bruteforce_loops() -> None:
    rng = np.random.default_rng(8)
    points = rng.uniform(-0.05, 0.05, (300, 3))
    hand = _random_hand(rng, 3, 5)
    hand[1][0, 3] = hand[0][0, 3]  # a degenerate capsule
    per_point = ref_penetration(points, *hand)
    expected = per_point.sum(1)
    args = [t64(x) for x in hand]
    pp = PenetrationPoints(points, n_clusters=16, dtype=F64)
    culled, dense = e_pen(pp, *args), e_pen_dense(t64(points), *args)
    np.testing.assert_allclose(culled.numpy(), expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(dense.numpy(), expected, rtol=1e-12, atol=1e-15)
    # the configuration has penetrating and clear points, including ones inside the palm box
    inside_box = [
        ref_box_sdf(q, hand[3][g], hand[4][g], hand[5]) < 0 for g in range(3) for q in points
    ]
    assert 0 < sum(inside_box)
    assert np.all((per_point > 0).sum(1) > 5) and np.all((per_point == 0).sum(1) > 100)


def test_penetration_points_clusters_are_balanced_and_bounded(brick_hull: np.ndarray) -> None:
    pp = PenetrationPoints(brick_hull, n_clusters=48, dtype=F64, leaf_size=8)
    sizes = [len(g) for g in pp._groups]
    assert sum(sizes) == 2000 and max(sizes) - min(sizes) <= 1
    assert sorted(np.concatenate(pp._groups).tolist()) == list(range(2000))
    assert pp.n_clusters == 48 and pp.fan == 5  # 2000 / (48 * 8) ~ 5 leaves per cluster
    leaf_sizes = [len(g) for g in pp._leaves]
    assert sorted(np.concatenate(pp._leaves).tolist()) == list(range(2000))
    assert max(leaf_sizes) - min(leaf_sizes) <= 1 and pp.leaf_members == max(leaf_sizes)
    # every coarse group is the union of its fan leaves
    for c, group in enumerate(pp._groups):
        leaves = pp._leaves[c * pp.fan : (c + 1) * pp.fan]
        assert sorted(np.concatenate(leaves).tolist()) == sorted(group.tolist())
        dist = np.linalg.norm(brick_hull[group] - pp.centers[c].numpy(), axis=1)
        assert dist.max() <= float(pp.rho[c])
        for f, leaf in enumerate(leaves):
            centre = pp.leaf_xyz.view(3, pp.fan, -1)[:, f, c].numpy()
            assert np.linalg.norm(brick_hull[leaf] - centre, axis=1).max() <= float(
                pp.leaf_rho[f, c]
            )
    # padded member table: (S, leaves) indices, coordinates slot-major
    members = pp.members.numpy()
    assert members.shape == (pp.leaf_members, 48 * pp.fan)
    xyz = pp.member_xyz.view(3, pp.leaf_members, -1).permute(1, 2, 0).numpy()
    np.testing.assert_array_equal(xyz, brick_hull[members])
    assert float(pp.rho.max()) < 0.03 and float(pp.leaf_rho.max()) < 0.015
    assert pp.to(torch.float32).dtype == torch.float32 and pp.to(F64) is pp


def _hands_around(hull: np.ndarray, rng: np.random.Generator, b: int, k: int = 16):
    """Realistic placements: capsule ends on/near hull points, palm box just off the surface."""
    radii = rng.uniform(0.006, 0.016, k)
    ends = rng.integers(len(hull), size=(b, k))
    outward = hull[ends] / np.linalg.norm(hull[ends], axis=-1, keepdims=True)
    p1 = hull[ends] + outward * (radii + rng.uniform(-0.004, 0.01, (b, k)))[..., None]
    p0 = p1 + rng.normal(scale=0.02, size=(b, k, 3))
    anchor = hull[rng.integers(len(hull), size=b)]
    center = anchor * 1.3
    rot = random_rotations(rng, b)
    half = np.array([0.035, 0.027, 0.006])
    return p0, p1, radii, center, rot, half


def _wrapped_hands(hull: np.ndarray, rng: np.random.Generator, b: int, k: int = 16):
    """Hands wrapped around (and through) the object: many points inside several primitives."""
    radii = rng.uniform(0.01, 0.03, k)
    p0 = rng.normal(scale=0.01, size=(b, k, 3))  # from near the centre of mass ...
    p1 = hull[rng.integers(len(hull), size=(b, k))] * 1.2  # ... out through the surface
    center = rng.normal(scale=0.01, size=(b, 3))
    rot = random_rotations(rng, b)
    half = np.array([0.045, 0.03, 0.02])
    return p0, p1, radii, center, rot, half


# culled (numba) vs dense (torch) differ by torch's square root, which is not always correctly
# rounded: 1 ulp per point distance at most
PEN_RTOL = {torch.float32: 1e-6, F64: 1e-12}


@pytest.mark.parametrize("dtype", [torch.float32, F64])
def test_e_pen_culled_equals_dense_on_real_hull(brick_hull: np.ndarray, dtype: torch.dtype) -> None:
    rng = np.random.default_rng(9)
    pp = PenetrationPoints(brick_hull, n_clusters=64, dtype=dtype)
    # one cluster of one leaf: the kernel then evaluates every point of every primitive near the
    # object, so its per-point depths are the unculled values computed by the same arithmetic
    flat = PenetrationPoints(brick_hull, n_clusters=1, dtype=dtype, leaf_size=len(brick_hull))
    assert flat.fan == 1
    far = list(_hands_around(brick_hull, rng, 4))
    far[0], far[1], far[3] = far[0] + 1.0, far[1] + 1.0, far[3] + 1.0  # nowhere near
    around = _hands_around(brick_hull, rng, 48)
    for i in (0, 1, 3):  # lift half of the hands off the object
        around[i][24:] *= 1.6
    configs = {
        "around": around,
        "wrapped": _wrapped_hands(brick_hull, rng, 16),
        "far": tuple(far),
    }
    eps = torch.finfo(dtype).eps
    for name, hand in configs.items():
        args = [torch.as_tensor(x, dtype=dtype) for x in hand]
        stats: dict[str, int] = {}
        culled = e_pen(pp, *args, stats=stats)
        dense = e_pen_dense(pp, *args)
        assert culled.dtype == dtype and culled.shape == (len(hand[0]),)
        torch.testing.assert_close(culled, dense, rtol=PEN_RTOL[dtype], atol=0.0, msg=name)
        # culling drops only exact zeros: per point, bit for bit the unculled kernel values
        depths = penetration_depths(pp, *args)
        assert depths.shape == (len(hand[0]), 2000) and depths.dtype == dtype
        assert torch.equal(depths, penetration_depths(flat, *args)), name
        assert torch.equal(culled, depths.sum(-1)), name
        # the same per-point values as the torch formulas, to rounding of the distance
        assert float((depths - _dense_depths(pp, *args)).abs().max()) <= 4 * eps * 0.1, name
        if name == "around":
            assert 0 < int((culled > 0).sum()) < len(culled)  # some grasps penetrate, some don't
            assert 0 < stats["point_evaluations"] < len(culled) * 2000 * 17 / 10  # culling works
        elif name == "wrapped":
            assert torch.all(culled > 1.0)  # deep, many points: eq. 11 sums hundreds of depths
        else:
            assert torch.all(culled == 0)
            assert stats["point_evaluations"] == 0
    # cluster count only changes the speed
    hand = [torch.as_tensor(x, dtype=dtype) for x in configs["around"]]
    reference = e_pen(pp, *hand)
    torch.testing.assert_close(reference, e_pen_dense(pp, *hand), rtol=PEN_RTOL[dtype], atol=0.0)
    for n_clusters, leaf_size in ((1, 1), (7, 8), (32, 3), (500, 8)):
        other = PenetrationPoints(brick_hull, n_clusters, dtype, leaf_size=leaf_size)
        assert torch.equal(e_pen(other, *hand), reference), (n_clusters, leaf_size)


def _dense_depths(pp: PenetrationPoints, p0, p1, radii, center, rot, half) -> torch.Tensor:
    """Per-point ``max(-d_H, 0)`` (B, M) from the elementwise torch formulas of e_pen_dense."""
    from graspstab.synthesis import penetration

    qx, qy, qz = pp.points.unbind(-1)
    cols = penetration._capsule_params(p0, p1, radii).permute(2, 0, 1)[..., None]
    per_capsule = penetration._capsule_distance(qx, qy, qz, *cols[:7].unbind(0))
    per_capsule = (cols[7] - per_capsule).clamp_min(0.0).amax(1)
    ctr = center.T[..., None]
    rot_t = rot.permute(1, 2, 0)[..., None]
    per_box = penetration._box_penetration(qx, qy, qz, ctr[0], ctr[1], ctr[2], rot_t, half)
    return torch.maximum(per_capsule, per_box)


def test_e_pen_wrapped_matches_bruteforce(brick_hull: np.ndarray) -> None:
    rng = np.random.default_rng(10)
    hand = _wrapped_hands(brick_hull, rng, 2, k=4)
    points = brick_hull[::10]
    expected = ref_e_pen(points, *hand)
    got = e_pen(PenetrationPoints(points, 8, F64), *[t64(x) for x in hand])
    np.testing.assert_allclose(got.numpy(), expected, rtol=1e-12)


# ---------------------------------------------------------------------------------------------
# batching: B > 1 equals a loop of B = 1 calls


def test_every_term_batched_equals_single(foam_brick_dir: Path, brick_hull: np.ndarray) -> None:
    rng = np.random.default_rng(11)
    b, n, k = 5, 120, 16
    sdf = TorchSDF.load(foam_brick_dir / "sdf.npz", dtype=F64)
    cand = t64(brick_hull[rng.integers(2000, size=(b, n))] + rng.normal(scale=0.01, size=(b, n, 3)))
    dist, normal = sdf.query(cand)
    p0, p1, radii, center, rot, half = (t64(x) for x in _hands_around(brick_hull, rng, b, k))
    pairs = torch.as_tensor([(i, j) for i in range(k) for j in range(i + 1, k) if j - i > 1])
    theta = t64(rng.normal(size=(b, 16)))
    lower, upper = -torch.ones(16, dtype=F64), torch.ones(16, dtype=F64)
    pp = PenetrationPoints(brick_hull, 64, F64)

    def all_terms(s: slice) -> list[torch.Tensor]:
        d, nrm = sdf.query(cand[s])
        return [
            d,
            nrm,
            e_dis(d),
            e_fc(cand[s], -nrm),
            e_pen(pp, p0[s], p1[s], radii, center[s], rot[s], half),
            e_pen_dense(pp, p0[s], p1[s], radii, center[s], rot[s], half),
            e_spen(p0[s], p1[s], radii, pairs),
            e_joint(theta[s], lower, upper),
        ]

    batched = all_terms(slice(None))
    assert torch.equal(batched[0], dist) and torch.equal(batched[1], normal)
    assert float(batched[4].max()) > 0 and float(batched[6].max()) > 0
    for g in range(b):
        single = all_terms(slice(g, g + 1))
        for i, (x, y) in enumerate(zip(batched, single, strict=True)):
            torch.testing.assert_close(x[g : g + 1], y, rtol=1e-13, atol=1e-15, msg=f"term {i}")


# ---------------------------------------------------------------------------------------------
# E_hpen (our addition: hand surface points inside the object)


def test_e_hpen_hand_computed() -> None:
    dist = torch.tensor([[-0.002, 0.001, -0.003, 0.0], [0.01, 0.02, 0.03, 0.04]], dtype=F64)
    np.testing.assert_allclose(e_hpen(dist).numpy(), [0.005, 0.0], atol=1e-15)


def test_e_hpen_sees_a_link_wholly_inside_where_e_pen_is_blind() -> None:
    """A capsule buried in a ball: eq. 11 (ball surface points inside the hand) is 0, E_hpen is
    not, and on the grid it equals the analytic depth sum ``sum max(R - |x|, 0)``."""
    radius_ball, r_cap = 0.05, 0.008
    ball = trimesh.creation.icosphere(subdivisions=5, radius=radius_ball)
    sdf = TorchSDF.from_grid(SDFGrid.build(ball, spacing=0.0015, margin=0.02), dtype=F64)
    rng = np.random.default_rng(0)
    surface = trimesh.sample.sample_surface(ball, 2000, seed=1)[0]
    # a capsule through the ball's centre, 3 cm long, and points on its surface
    p0, p1 = np.array([-0.015, 0.0, 0.0]), np.array([0.015, 0.0, 0.0])
    t = rng.uniform(0, 1, 300)
    direction = rng.normal(size=(300, 3))
    direction[:, 0] = 0.0
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    hand_points = p0 + t[:, None] * (p1 - p0) + r_cap * direction
    pen = e_pen(
        PenetrationPoints(surface, 8, F64),
        torch.as_tensor(p0[None, None]),
        torch.as_tensor(p1[None, None]),
        torch.tensor([r_cap], dtype=F64),
        torch.tensor([[1.0, 1.0, 1.0]], dtype=F64),  # palm box far away
        torch.eye(3, dtype=F64)[None],
        torch.tensor([0.001, 0.001, 0.001], dtype=F64),
    )
    assert float(pen[0]) == 0.0
    dist = sdf.query(torch.as_tensor(hand_points[None]))[0]
    expected = np.maximum(radius_ball - np.linalg.norm(hand_points, axis=1), 0).sum()
    got = float(e_hpen(dist)[0])
    assert got > 0.0
    # the icosphere's facets sit up to ~0.05 mm inside the true sphere; grid error < 0.85 mm
    assert abs(got - expected) < 300 * 1e-3
    assert abs(got - expected) / expected < 0.03
    # moved out of the ball, the capsule costs nothing
    far = torch.as_tensor(hand_points[None] + np.array([0.2, 0.0, 0.0]))
    assert float(e_hpen(sdf.query(far)[0])[0]) == 0.0
