"""The GIMP basis in 3D: point domains as tetrahedra (ibm.discretise.simplex_domains), clipped by the grid
cells, trilinear N integrated exactly on the pieces (ibm.discretise.basis.gimp_basis)."""
import numpy as np
import pytest
import shapely

from ibm.discretise.basis import gimp_basis, mpm_basis
from ibm.geometry.frames import frame_3d
from ibm.discretise.grid import Grid
from ibm.geometry.polyhedron import box, material_points
from ibm.discretise.simplex_domains import SimplexDomains

KINDS = ("roller", "roller", "free", "roller", "roller", "roller")
SHEAR = np.array([[1.1, 0.2, 0.0], [0.05, 0.9, 0.1], [0.0, -0.1, 1.2]])   # det 1.2 ...: a homogeneous F


def _oblique(size=(10.0, 50.0, 10.0), h=50 / 8):
    body = box(size, KINDS, frame_3d(30.0, 20.0), (0.3, 0.2, 0.1))
    grid = Grid.covering(body, h, margin=2)
    return body, grid, material_points(body, grid, 2, rule=False, domains=True)


def test_the_domains_are_the_clipped_cubes():
    body, grid, points = _oblique()
    domains = points.domains
    assert domains.n == len(points) and np.all(np.diff(domains.owner) >= 0)
    assert np.abs(domains.volumes() - points.volume).max() <= 1e-12 * points.volume.max()
    assert abs(domains.volumes().sum() - body.volume) <= 1e-12 * body.volume


@pytest.mark.parametrize("deformed", [False, True])
def test_gimp_reproduces_linear_fields_to_round_off(deformed):
    """sum_v S_v = 1, sum_v dS_v = 0, sum_v S_v x_v = the domain's centroid and sum_v x_v dS_v^T = I,
    on the oblique column's 356 points (cut cubes included), as made and mapped by a homogeneous F."""
    body, grid, points = _oblique()
    x, domains = points.x, points.domains
    if deformed:
        x = x @ SHEAR.T
        domains = domains.mapped(points.x, x, np.broadcast_to(SHEAR, (len(x), 3, 3)))
        assert np.abs(domains.volumes() - points.volume * np.linalg.det(SHEAR)).max() <= 1e-12
    basis = gimp_basis(grid, x, domains)
    X = grid.nodes()[basis.nodes]                                          # (n, k, 3)
    assert basis.S.shape == (len(x), 27) and basis.S.min() >= -1e-15
    assert np.abs(basis.S.sum(axis=1) - 1).max() < 1e-13
    assert np.abs(basis.dS.sum(axis=1)).max() < 1e-14
    assert np.abs(np.einsum("pk,pkd->pd", basis.S, X) - x).max() < 1e-12
    assert np.abs(np.einsum("pka,pkb->pab", basis.dS, X) - np.eye(3)).max() < 1e-12


def test_a_box_domain_inside_one_cell_is_the_standard_basis():
    """The mean of a trilinear N over a box is N at its centre (a product of linear factors)."""
    grid = Grid(2.0, (0, 0, 0), (3, 3, 3))
    from ibm.geometry.polytope import box_simplices
    lo = np.array([[2.3, 2.1, 3.2], [0.1, 4.5, 1.0]])
    hi = lo + np.array([[0.5, 0.7, 0.4], [1.8, 1.2, 0.9]])
    vertices, owner = box_simplices(lo, hi)
    centre = (lo + hi) / 2
    gimp = gimp_basis(grid, centre, SimplexDomains(vertices, owner, 2))
    mpm = mpm_basis(grid, centre)
    for p in range(2):                       # gimp's window is the one cell's 8 nodes here
        order = np.argsort(gimp.nodes[p])
        assert np.array_equal(gimp.nodes[p][order], np.sort(mpm.nodes[p]))
        assert np.allclose(gimp.S[p][order], mpm.S[p][np.argsort(mpm.nodes[p])], atol=1e-15)
        assert np.allclose(gimp.dS[p][order], mpm.dS[p][np.argsort(mpm.nodes[p])], atol=1e-15)


def _hat_means(z0: float, z1: float, h: float, nodes: int) -> np.ndarray:
    """(nodes,) the mean over [z0, z1] of the 1D hat functions at 0, h, .., (nodes - 1) h (exact)."""
    def integral(z, k):          # int_-inf^z of the hat at k h
        t = np.clip(z / h - k, -1, 1)
        return h * np.where(t < 0, (t + 1) ** 2 / 2, 0.5 + t - t * t / 2)
    return np.array([integral(z1, k) - integral(z0, k) for k in range(nodes)]) / (z1 - z0)


def test_a_prism_domain_is_the_2d_gimp_times_the_1d_one():
    """A prism P x [z0, z1] (P a polygon across several cells, as tetrahedra) against the 2D basis of
    P (shapely pieces, another code path) times the hat means along z: S and dS to round-off."""
    rng = np.random.default_rng(7)
    h = 1.0
    grid3, grid2 = Grid(h, (0, 0, 0), (6, 6, 6)), Grid(h, (0, 0), (6, 6))
    for _ in range(4):
        angles = np.sort(rng.uniform(0, 2 * np.pi, 7))
        ring = np.array([3.0, 3.0]) + rng.uniform(0.6, 1.4) * np.stack([np.cos(angles), np.sin(angles)], 1)
        polygon = shapely.Polygon(ring)
        z0, z1 = sorted(rng.uniform(0.5, 5.5, 2))
        triangles = np.stack([np.repeat(ring[:1], 5, 0), ring[1:-1], ring[2:]], axis=1)          # (5, 3, 2)
        a = [np.column_stack([triangles[:, i], np.full(5, z0)]) for i in range(3)]
        b = [np.column_stack([triangles[:, i], np.full(5, z1)]) for i in range(3)]
        tets = np.concatenate([np.stack(t, 1) for t in ((a[0], a[1], a[2], b[0]), (a[1], a[2], b[0], b[1]),
                                                         (a[2], b[0], b[1], b[2]))])
        centroid2 = np.array(polygon.centroid.coords[0])
        x3 = np.append(centroid2, (z0 + z1) / 2)[None]
        three = gimp_basis(grid3, x3, SimplexDomains(tets, np.zeros(len(tets), int), 1))
        two = gimp_basis(grid2, centroid2[None], np.array([polygon]))
        along = _hat_means(z0, z1, h, 7)
        slope = np.array([(_hat_step(z1, k, h) - _hat_step(z0, k, h)) / (z1 - z0) for k in range(7)])
        S, dS = np.zeros((7, 7, 7)), np.zeros((7, 7, 7, 3))                # full node lattice (i, j, k)
        i3, j3, k3 = np.unravel_index(three.nodes[0], (7, 7, 7), order="F")
        np.add.at(S, (i3, j3, k3), three.S[0])
        np.add.at(dS, (i3, j3, k3), three.dS[0])
        S2, dS2 = np.zeros((7, 7)), np.zeros((7, 7, 2))
        i2, j2 = np.unravel_index(two.nodes[0], (7, 7), order="F")
        np.add.at(S2, (i2, j2), two.S[0])
        np.add.at(dS2, (i2, j2), two.dS[0])
        assert np.abs(S - S2[:, :, None] * along[None, None]).max() < 1e-14
        assert np.abs(dS[..., :2] - dS2[:, :, None, :] * along[None, None, :, None]).max() < 1e-13
        assert np.abs(dS[..., 2] - S2[:, :, None] * slope[None, None]).max() < 1e-13


def _hat_step(z: float, k: int, h: float) -> float:
    """The hat at k h itself at z (its integral's derivative)."""
    return max(0.0, 1 - abs(z / h - k))


def test_a_uniform_stress_leaves_no_force_on_interior_nodes():
    """The finite-strain patch test in 3D: a 40^3 cube at (30, 20) mapped by a homogeneous F, a
    uniform Cauchy stress; the internal forces sum_p V_p sigma dS_p vanish at every node whose
    support lies inside the mapped body (to round-off), and sum over all nodes to zero."""
    body, grid, points = _oblique((40.0, 40.0, 40.0), 5.0)
    x = points.x @ SHEAR.T
    domains = points.domains.mapped(points.x, x, np.broadcast_to(SHEAR, (len(x), 3, 3)))
    grid = Grid(grid.h, tuple(int(v) for v in np.floor(x.min(0) / grid.h) - 3),
                tuple(int(v) for v in np.ceil((x.max(0) - x.min(0)) / grid.h) + 6))
    basis = gimp_basis(grid, x, domains)
    sigma = np.array([[3.0, 1.0, -0.5], [1.0, -2.0, 0.7], [-0.5, 0.7, 1.5]])
    volume = domains.volumes()
    force = np.zeros((grid.n_nodes, 3))
    np.add.at(force, basis.nodes.ravel(), (volume[:, None, None] * basis.dS @ sigma).reshape(-1, 3))
    assert np.abs(force.sum(axis=0)).max() < 1e-10 * np.abs(sigma).max() * volume.sum() / grid.h
    # the mapped body: faces' planes mapped by F (n -> F^-T n), the node's support cube inside all
    normals = body.normals @ np.linalg.inv(SHEAR)
    offsets = body.offsets
    lengths = np.linalg.norm(normals, axis=1)
    nodes = grid.nodes()
    clearance = (nodes @ normals.T - offsets) / lengths - np.sqrt(3) * grid.h
    interior = np.all(clearance > 0, axis=1)
    assert interior.sum() >= 50
    scale = np.abs(sigma).max() * grid.h ** 2
    assert np.abs(force[interior]).max() < 1e-12 * scale
    assert np.abs(force[~interior]).max() > 1e-3 * scale          # the boundary nodes do carry force
