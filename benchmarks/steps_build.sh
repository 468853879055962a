#!/usr/bin/env bash
# STEPS (Simulation Toolkit for Electrical Power Systems, https://github.com/changgang/steps, MIT)
# built from its source and its Python wrapper installed into the current Python, for the
# independent salient-pole sets (test/steps_plant.py, benchmarks/steps_sets.py).
#
#     benchmarks/steps_build.sh STEPS_SOURCE_DIR [PYTHON]
#
# Why from source: the stepspy wheel on the package index ships a libSTEPS.so that needs glibc
# 2.38 (Debian 12 has 2.36), and its 2.5.0 wrapper refuses an older library; the wrapper of the
# same source tree (python/stepspy-current) fits the library built here. Needs g++ and
# Debian's cbp2make (the sources come with Code::Blocks projects); about 4 minutes with make -j2.
set -euo pipefail
src=$(cd "${1:?STEPS source directory (a clone of changgang/steps)}" && pwd)
python=${2:-python3}
command -v cbp2make >/dev/null || { echo "needs cbp2make (apt install cbp2make)" >&2; exit 1; }
cd "$src/code/thirdparty"
for p in csparse cxsparse cpptest; do
  cbp2make -in "$p.cbp" -out "$p.mk" >/dev/null
  make -s -f "$p.mk" release -j2
done
cd "$src/code/steps"
cbp2make -in STEPS.cbp -out STEPS.mk >/dev/null
make -s -f STEPS.mk release -j2
# the wrapper loads libSTEPS.so from its own package folder
cp "$src/build/bin/release/libSTEPS.so" "$src/python/stepspy-current/stepspy/libsteps/"
"$python" -m pip install -q -e "$src/python/stepspy-current"
"$python" -c "from stepspy import STEPS; STEPS(is_default=False, log_file='/dev/null'); print('stepspy ready')"
