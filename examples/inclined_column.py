"""
Large deformation: a column settling under its own weight down walls inclined at 30 degrees.
============================================================================================

The column (10 wide, 50 high, E = 1e4, nu = 0, rho_0 g H = 40000) halves its height in 40 load
steps while its material slides about 26 units down two roller walls that cut the grid anywhere.
The exact solution is the Lambert-W column (studies.problems.finite_strain). The figure shows every
point's sigma_eta_eta at the end against its initial height, beside the exact curve.

    python examples/inclined_column.py [figure.png]
"""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from studies.run.case import CaseSpec, run_case  # noqa: E402


def main(path: str | None = "inclined_column.png", method: str = "nitsche", cells: int = 16) -> dict:
    spec = CaseSpec(problem="column", method=method, angle=30, cell=50 / cells, ppc=2, offset=(0.3, 0.2),
                    E=1e4, nu=0.0, load=40000, width=10, height=50, kinematics="large", steps=40, basis="gimp")
    record = run_case(spec, keep_fields=True)
    fields = record.pop("fields")
    eta = (fields["X"] - fields["corner"]) @ fields["frame"][:, 1]      # initial height of each point
    order = np.argsort(eta)
    print(f"{method}, h = {spec.cell:g}: err_sigma_ample {record['err_sigma_ample']:.3e}, "
          f"top at {record['height_final']:.4f} (exact {record['height_exact']:.4f}), "
          f"{sum(record['newton_iterations'])} Newton iterations in {record['steps']} steps")
    if path:
        fig, ax = plt.subplots(figsize=(5, 4))
        ax.plot(fields["sigma_eta"][-1][order], eta[order], "o", ms=3, mfc="none", label=f"{method}, points")
        ax.plot(fields["sigma_exact"][-1][order], eta[order], "-", color="black", label="exact (Lambert W)")
        ax.set_xlabel("σ_ηη at the last step")
        ax.locator_params(axis="x", nbins=5)
        ax.set_ylabel("initial height η")
        ax.legend()
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return {**record, "fields": fields}


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "inclined_column.png")
