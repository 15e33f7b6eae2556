"""
A body of your own, every boundary method on it: a patch test on an inclined pentagon.
======================================================================================

A convex pentagon at 20° (counter-clockwise vertices, one kind per edge) under a uniform in-plane
pressure p: the exact state is sigma = -p I, u = eps x with eps = -p / (2 (lam + mu)). Rollers on
two edges get their normal displacement from the exact field through the lift; the other edges
carry the traction -p n. Consistent methods reproduce a linear field to round-off, the IBM and
penalty to O(δ) and O(1/β₀); the body-fitted `fem` reference meshes the pentagon (gmsh).

    python examples/custom_body.py
"""
import numpy as np

from baselines.registry import METHODS
from ibm.norms import point_errors
from ibm.geometry.outline import Body
from ibm.models.elastic import Elastic
from ibm.small.model import Loads, build_model

PRESSURE = 10.0
# the two rollers meet at a right angle (the IBM's bands of rollers may overlap only so)
_ALONG = np.array([np.cos(np.radians(20)), np.sin(np.radians(20))])
_ACROSS = np.array([-_ALONG[1], _ALONG[0]])
_CORNER = np.array([3.7, 2.9])
VERTICES = np.array([_CORNER, _CORNER + 80 * _ALONG, [90.0, 75.0], [30.0, 100.0], _CORNER + 60 * _ACROSS])
KINDS = ("roller", "traction", "traction", "traction", "roller")


def exact(material: Elastic, x: np.ndarray):
    strain = -PRESSURE / (2 * (material.lam + material.mu))
    u = strain * x
    grad = np.broadcast_to(strain * np.eye(2), (len(x), 2, 2)).copy()
    sigma = np.broadcast_to(-PRESSURE * np.eye(2), (len(x), 2, 2)).copy()
    return u, grad, sigma, np.full(len(x), material.lam * 2 * strain)


def main(methods=("ibm", "penalty", "nitsche", "lagrange", "fem"), h: float = 10.0) -> dict[str, dict]:
    body = Body(VERTICES, KINDS)
    material = Elastic(1e4, 0.3)
    tractions = {k: (lambda n: lambda x: np.broadcast_to(-PRESSURE * n, (len(x), 2)).copy())(-body.normals[k])
                 for k in range(body.n_edges) if KINDS[k] == "traction"}   # sigma n with the outward n
    loads = Loads(tractions=tractions, lift=lambda x: exact(material, x)[:2])
    model = build_model(body, material, loads, h, ppc=2)
    results = {}
    for name in methods:
        solution = METHODS[name](model)                 # each method with its default parameters
        u, _, sigma, zz = exact(material, model.points.x)
        results[name] = point_errors(model.points.volume, solution.u, u, solution.sigma, sigma,
                                     solution.sigma_zz, zz, np.array([0.0, 1.0]))
        print(f"{name:>9}: err_u {results[name]['err_u']:.2e}  err_sigma {results[name]['err_sigma']:.2e}")
    return results


if __name__ == "__main__":
    main()
