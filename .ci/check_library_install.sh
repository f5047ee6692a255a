#!/usr/bin/env bash
# The library alone, as a user installs it: `pip install .` into a fresh venv WITHOUT the
# workflow extra (no Snakemake), from outside the source tree; then `import facemotion`, read a
# C3D file, run the tutorial's code cells (plain Python, no Jupyter) and the command line.
set -euo pipefail
cd "$(dirname "$0")/.."
REPO=$PWD
PY=${PY:-python3.11}
command -v "$PY" >/dev/null 2>&1 || PY=python3
SHARED=${FACEMOTION_SHARED_DATA:-$REPO/../shared/data}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
"$PY" -m venv "$TMP/venv"
"$TMP/venv/bin/pip" install --quiet --upgrade pip
"$TMP/venv/bin/pip" install --quiet -c constraints.txt "$REPO"
cd "$TMP"
export FACEMOTION_SHARED_DATA="$SHARED" MPLBACKEND=Agg
"$TMP/venv/bin/python" - "$REPO/docs/tutorial.ipynb" <<'PYEOF'
import importlib.util
import json
import os
import sys

assert importlib.util.find_spec("snakemake") is None, "Snakemake is installed"
import facemotion as fm

assert "site-packages" in fm.__file__, fm.__file__
take = fm.read(os.path.join(os.environ["FACEMOTION_SHARED_DATA"], "animface",
                            "animface_jaw.c3d"))
print(f"read {take.n_markers} markers x {take.n_frames} frames at {take.rate:g} Hz")
os.chdir(os.path.dirname(sys.argv[1]))  # the notebook's own directory, as in Jupyter
cells = [c for c in json.load(open(sys.argv[1]))["cells"] if c["cell_type"] == "code"]
ns = {}
for i, cell in enumerate(cells, 1):
    src = "".join(line for line in cell["source"] if not line.lstrip().startswith("%"))
    exec(compile(src, f"tutorial cell {i}", "exec"), ns)
print(f"tutorial: {len(cells)} code cells ran; Table I first row:",
      ns["table_1"].iloc[0].tolist())
PYEOF
"$TMP/venv/bin/facemotion" info "$SHARED/animface/animface_jaw.c3d" --no-markers
set +e
msg=$("$TMP/venv/bin/facemotion" study -n 2>&1)
rc=$?
set -e
if [[ $rc -ne 1 || $(printf '%s\n' "$msg" | wc -l) -ne 1 || $msg != *"facemotion[workflow]"* ]]; then
  echo "facemotion study without Snakemake: expected a one-line error, got (exit $rc): $msg"
  exit 1
fi
echo "facemotion study without Snakemake: $msg"
echo "library install without Snakemake: OK"
