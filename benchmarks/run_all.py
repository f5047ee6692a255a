"""`make bench`: the QR analysis against its baselines (bench_qr.py), the dense-data cases that
run in minutes (bench_dense.py: GEMM peak, ranking at 10x the frames, loading 20,000 frames,
the TRC reader), the default study three times (bench_study.py), then the default study with
this code against the last commit before one job per dataset, alternating
(bench_before_after.py); each writes its table into docs/performance.md between its markers,
and nothing else in the repository.

    python benchmarks/run_all.py [--quick]
"""

import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

if __name__ == "__main__":
    quick = ["--quick"] if "--quick" in sys.argv[1:] else []
    page = str(HERE.parent / "docs" / "performance.md")
    rc = subprocess.call([sys.executable, str(HERE / "bench_qr.py"), *quick, "--page", page])
    # the cases that run in minutes; mem4g, dense and talker: see docs/performance.md
    rc |= subprocess.call([sys.executable, str(HERE / "bench_dense.py"), *quick, "--only",
                           "peak", "rank10x", "load20k", "reader", "--page", page])
    # hours of dense faces, streamed: the 468-point hour, 5,023 points x 25,000 frames, the C3D
    # at its frame limit, the parsers judged and the exponents (docs/performance.md; the 10 GB
    # case runs alone)
    rc |= subprocess.call([sys.executable, str(HERE / "bench_stream.py"), "--cases", "trc468",
                           "trc5023", "c3d65k", "--parsers", "--fit", "--page", page])
    rc |= subprocess.call([sys.executable, str(HERE / "bench_study.py"), "--repeat", "3",
                           "--page", page])
    rc |= subprocess.call([sys.executable, str(HERE / "bench_before_after.py"), "--repeat", "3",
                           "--page", page])
    sys.exit(rc)
