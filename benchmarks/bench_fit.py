"""make bench: error against run time of every fit method and optimiser.

Prints a Markdown table: parameter errors against the synthetic truth, the data's log-RMSE
and the median time of the whole fit (one ink: ~130 configurations × 41 wavelengths).
Targets: refined fit < 50 ms, the paper's two steps < 10 ms. The time of the
refined method is the whole default fit (the two steps run first and are reported too).
``--quick`` runs one case.
"""

import sys
import time

from gonio_cli.fit.sweep import (comparison_sweep, format_comparison, format_rows,
                                  goniochromatic_sweep)


def main() -> None:
    quick = "--quick" in sys.argv
    t = time.perf_counter()
    rows = goniochromatic_sweep(alphas=(0.19,) if quick else (0.03, 0.19, 0.5),
                                inks=("red",) if quick else ("red", "green", "blue"),
                                repeats=3 if quick else 7)
    print("## gonio fit: goniochromatic (seed 000 eq. 5), synthetic data, 2 % noise\n")
    print(format_rows(rows))
    print("\n## Comparison models on their own synthetic data (2 % noise, θi 20–70°, 41 wavelengths)\n")
    print(format_comparison(comparison_sweep(repeats=3 if quick else 7)))
    print(f"\n({time.perf_counter() - t:.1f} s for the sweep)")


if __name__ == "__main__":
    main()
