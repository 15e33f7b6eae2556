"""
The seed paper's validation, reproduced: the confined block at 90, 45 and 30 degrees.
=====================================================================================

A 100 x 100 plane-strain block with rollers on its base and sides and a pressure on its top,
in a grid of h = 10 that its edges cut anywhere; the exact solution is linear, so every error is
the method's own. The seed's implicit boundary method (δ/h = 1e-5) beats the paper's numbers.

    python examples/seed_reproduction.py
"""
from studies.run.seed import seed_table


def main() -> list[dict]:
    rows = seed_table()
    for row in rows:
        print(f"{row['angle']:>4}°  err_u {row['err_u']:.2e} (paper {row['paper_err_u']:.2e})   "
              f"err_sigma {row['err_sigma']:.2e} (paper {row['paper_err_sigma']:.2e})")
    return rows


if __name__ == "__main__":
    main()
