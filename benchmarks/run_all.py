"""All benchmarks: the QR analysis against its naive baselines, dense data and memory
(bench_dense.py), then the full study's time.

    python benchmarks/run_all.py [--quick]
"""

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    quick = ["--quick"] if "--quick" in sys.argv[1:] else []
    rc = subprocess.call([sys.executable, str(HERE / "bench_qr.py"), *quick])
    rc |= subprocess.call([sys.executable, str(HERE / "bench_dense.py"), *quick])
    rc |= subprocess.call([sys.executable, str(HERE / "bench_study.py"), "--repeat", "3",
                           "--readme", str(HERE.parent / "README.md")])
    sys.exit(rc)
