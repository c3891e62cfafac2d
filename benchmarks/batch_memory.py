"""Peak memory of `wallbatch run` of a 10,000-case sweep against the same sweep with 1,000 cases
(the `memory-10k-cases` row of benchmarks/suite.py, with both numbers printed).

    python benchmarks/batch_memory.py [--scale 1.0]

The results file is written block by block from the parts (io/netcdf.py `write_results_file`),
so the final pass adds about a block of cases (BLOCK_BYTES of outputs) to what the run holds.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("WALLBATCH_THREADS", "1")
sys.path.insert(0, str(Path(__file__).resolve().parent))

import suite  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", type=float, default=1.0)
    args = ap.parse_args()
    suite.SCALE = args.scale
    row = suite.memory_10k()
    print(f"{row['scene']}: {row['wb']}; {row['note']}; ratio {row['value']:.3f} (target <= 1.5)")


if __name__ == "__main__":
    main()
