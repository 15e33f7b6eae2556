"""Rigid bodies: the outline's gap and normal (polygons at sides and corners, circles), the linearised
rigid motion, and contact with a rigid body inside the load steps: the frictional block on a rigid
slab is the block on its wall to round-off, with the force and moment on the slab exact; a slab that
moves carries the block along."""
import numpy as np
import pytest

from baselines.registry import METHODS, treatment
from ibm.contact.rigid import RigidBody, moment
from ibm.exceptions import InputError
from ibm.geometry.outline import rectangle
from ibm.large.load_paths import LoadPath
from ibm.large.loadsteps import Loading, Setup, run
from studies.problems.frictional_block import FRICTIONAL_BLOCK
from studies.run.case import CaseSpec

SQUARE = RigidBody(vertices=[[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0]])


def test_polygon_gap_and_normal_at_sides_corners_and_inside():
    x = np.array([[1.0, -0.5], [3.0, 1.0], [3.0, 3.0], [1.0, 1.8], [1.0, 0.0]])
    gap, normal = SQUARE.gap(x)
    assert gap == pytest.approx([0.5, 1.0, np.sqrt(2), -0.2, 0.0])
    assert normal == pytest.approx(np.array([[0, -1], [1, 0], [np.sqrt(0.5)] * 2, [0, 1], [0, -1]]))
    assert SQUARE.pivot == pytest.approx([1.0, 1.0])


def test_polygon_features_split_sides_from_corners():
    """A multiplier's piece stops where the closest feature changes: the sides 0-3, the corners 4-7."""
    x = np.array([[1.0, -0.5], [3.0, 1.0], [3.0, 3.0], [1.0, 1.8], [-1.0, -1.0], [-0.5, 1.0]])
    assert SQUARE.features(x).tolist() == [0, 1, 6, 2, 4, 3]
    assert RigidBody(center=[0.0, 0.0], radius=1.0).features(x).tolist() == [0] * 6


def test_circle_gap_and_normal():
    circle = RigidBody(center=[1.0, 2.0], radius=0.5)
    gap, normal = circle.gap(np.array([[1.0, 0.0], [1.3, 2.0]]))
    assert gap == pytest.approx([1.5, -0.2]) and normal == pytest.approx(np.array([[0.0, -1.0], [1.0, 0.0]]))


def test_rigid_motion_is_a_translation_and_a_small_rotation_about_the_pivot():
    path = LoadPath([0.0, 1.0], [[0.0, 0.0, 0.0], [0.1, -0.2, 0.01]])
    body = RigidBody(vertices=SQUARE.vertices, motion=path, pivot=[0.0, 0.0])
    u = body.displacement(np.array([[2.0, 0.0], [0.0, 3.0]]), 0.5)
    assert u == pytest.approx(np.array([[0.05, -0.1 + 0.005 * 2], [0.05 - 0.005 * 3, -0.1]]))
    # the moment of a couple is the same about every pivot
    x, force = np.array([[0.0, 0.0], [1.0, 0.0]]), np.array([[0.0, -1.0], [0.0, 1.0]])
    assert moment(x, force, np.zeros(2)) == pytest.approx(1.0) == moment(x, force, np.array([5.0, -3.0]))


@pytest.mark.parametrize("changes, words", [
    ({"vertices": [[0, 0], [0, 1], [1, 0]]}, "counter-clockwise"),
    ({"vertices": [[0, 0], [1, 0]]}, "three or more"),
    ({"center": [0.0, 0.0], "radius": -1.0}, "radius > 0"),
    ({"vertices": [[0, 0], [1, 0], [0, 1]], "center": [0.0, 0.0], "radius": 1.0}, "one of the two"),
    ({"vertices": [[0, 0], [1, 0], [0, 1]], "motion": LoadPath([0, 1], [[0, 0], [1, 1]])}, r"\(c_x, c_y, theta\)"),
])
def test_bad_rigid_bodies_are_one_line(changes, words):
    with pytest.raises(InputError, match=words):
        RigidBody(**changes)


BLOCK = CaseSpec(problem="frictional-block", method="nitsche", angle=30.0, ppc=2, steps=8, friction=0.3)


def _on_slab(spec, motion=None, top=None):
    """The frictional block with its base a free edge on a rigid slab (100 below it, 50 beyond each end) in
    place of its wall; `top` the top plate's translations (default: the block's own)."""
    setup, corner, R, at = FRICTIONAL_BLOCK.setup(spec)
    body = rectangle(spec.width, spec.height, ("free", "traction", "fixed", "traction"), spec.angle, corner)
    local = np.array([[-50.0, -100.0], [spec.width + 50, -100.0], [spec.width + 50, 0.0], [-50.0, 0.0]])
    slab = RigidBody(vertices=corner + local @ R.T, motion=motion)
    path = setup.loading.wall_path
    top = LoadPath(path.times, path.values[:, 1:]) if top is None else top
    loading = Loading(wall_path=top, traction_path=setup.loading.traction_path)
    return Setup(body, setup.material, loading, spec.cell, spec.ppc, spec.basis, spec.steps,
                 contact={0: setup.contact[0]}, obstacles={0: slab}), slab, R, at


@pytest.mark.parametrize("method", ["penalty", "nitsche", "lagrange"])
def test_block_on_a_rigid_slab_is_the_block_on_its_wall(method):
    spec = BLOCK.with_(method=method)
    wall_setup, *_ = FRICTIONAL_BLOCK.setup(spec)
    used = METHODS[method].used({}, load_steps=True)
    on_wall = run(wall_setup, treatment(method, used))
    setup, slab, R, at = _on_slab(spec)
    on_slab = run(setup, treatment(method, used))
    # the same to Newton's tolerance (stresses near 10; Nitsche's differ by 1.3e-8)
    assert np.abs(on_slab.sigma - on_wall.sigma).max() < 1e-7
    assert np.abs(on_slab.x - on_wall.x).max() < 1e-8
    for step, wall_step in zip(on_slab.steps, on_wall.steps):
        force = np.array([step["obstacle_force_x"], step["obstacle_force_y"]])
        assert force == pytest.approx([wall_step["contact_force_x"], wall_step["contact_force_y"]], rel=1e-9, abs=1e-9)
        pressure, tau, _ = at(step["t"])
        # about the slab's centroid (50, -50) in the block's frame: the pressure's moment cancels, the
        # shear on the base (tau W at 50 above the centroid) gives -50 tau W
        # (the penalty to its O(1/beta0): 1.3e-6 of the moment in the last step)
        bound = 5e-6 if method == "penalty" else 1e-8
        assert step["obstacle_moment"] == pytest.approx(-50 * tau * 100, rel=bound, abs=bound * pressure * 100)
        assert step["slip_length"] == pytest.approx(wall_step["slip_length"], abs=1e-9)


def test_a_moving_slab_carries_the_block_along():
    """The slab moves by minus the top plate's path and the plate stays: the same stresses, the displacements
    shifted by the slab's translation."""
    spec = BLOCK.with_(method="lagrange")
    setup, slab, R, at = _on_slab(spec)
    still = run(setup, treatment("lagrange", METHODS["lagrange"].used({}, load_steps=True)))
    path = setup.loading.wall_path
    motion = LoadPath(path.times, np.concatenate([-path.values[:, 0], np.zeros((len(path.times), 1))], axis=1))
    moving_setup, *_ = _on_slab(spec, motion, LoadPath(path.times, np.zeros_like(path.values)))
    moving = run(moving_setup, treatment("lagrange", METHODS["lagrange"].used({}, load_steps=True)))
    assert np.abs(moving.sigma - still.sigma).max() < 1e-8
    assert np.abs((moving.x - moving.X) - (still.x - still.X) + path.values[-1, 0]).max() < 1e-9
