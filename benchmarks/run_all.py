"""`make bench`: the QR analysis against its baselines (bench_qr.py), the dense-data cases that
run in minutes (bench_dense.py: GEMM peak, ranking at 10x the frames, loading 20,000 frames,
the TRC reader), then the default study three times (bench_study.py); each writes its table
into README.md between its markers.

    python benchmarks/run_all.py [--quick]
"""

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    quick = ["--quick"] if "--quick" in sys.argv[1:] else []
    readme = str(HERE.parent / "README.md")
    rc = subprocess.call([sys.executable, str(HERE / "bench_qr.py"), *quick,
                          "--readme", readme])
    # the cases that run in minutes; mem4g, dense and talker: see the README
    rc |= subprocess.call([sys.executable, str(HERE / "bench_dense.py"), *quick, "--only",
                           "peak", "rank10x", "load20k", "reader", "--readme", readme])
    rc |= subprocess.call([sys.executable, str(HERE / "bench_study.py"), "--repeat", "3",
                           "--readme", readme])
    sys.exit(rc)
