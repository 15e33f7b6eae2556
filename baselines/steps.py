"""The baselines inside the large-deformation loop (ibm.treatment's interface).

- `nodal`: strong constraints on the grid nodes lying on each wall (AMPLE's and most MPM codes'
  way); a wall that does not lie on a grid line, at every step, is refused.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ibm.geometry import InputError
from ibm.treatment import StepContext, StepTerms

ON_LINE = 1e-9   # relative to h: how far a wall may be from a grid line and still count as on it


@dataclass(frozen=True)
class Nodal:
    """Nodes on a wall line get the wall's motion: its normal component (roller) or both (fixed)."""

    def step(self, context: StepContext) -> StepTerms:
        grid, body = context.grid, context.body
        nodes = grid.nodes()
        dofs, values = [], []
        for wall, edge in enumerate(body.essential_edges):
            n = context.lines.normals[wall]
            axis = int(np.argmax(np.abs(n)))
            coordinate = context.lines.points[wall][axis]
            offset = coordinate / grid.h - np.round(coordinate / grid.h)
            if abs(abs(n[axis]) - 1) > 1e-12 or abs(offset) > ON_LINE:
                raise InputError(f"method 'nodal' needs every wall on a grid line; the wall of edge {edge} "
                                 f"(normal ({n[0]:.6g}, {n[1]:.6g}), through ({context.lines.points[wall][0]:.6g}, "
                                 f"{context.lines.points[wall][1]:.6g})) is not; use an angle of 0, 90, 180 "
                                 "or 270 degrees and an offset putting the walls on grid lines")
            on = np.flatnonzero(np.abs(nodes[:, axis] - coordinate) <= ON_LINE * grid.h)
            g = context.wall_vector(wall)
            components = [axis] if body.kinds[edge] == "roller" else [0, 1]
            for c in components:
                dofs.append(2 * on + c)
                values.append(np.full(len(on), g[c]))
        dofs, values = np.concatenate(dofs), np.concatenate(values)
        dofs, first = np.unique(dofs, return_index=True)
        return StepTerms(fixed=(dofs, values[first]), info={"n_fixed": len(dofs)})
