#!/bin/bash
# The checks of a GPU session in one call (for the device tool, whose time is short):
# the versions, the render iteration at 1M triangles x 24 views x 512² with and without the
# fused Triton kernels (and torch.profiler's table by op), the GPU tests, a whole default
# construction on CUDA. Logs and JSON under $OUT (default /tmp/device_check).
#     bash bench/device_check.sh
#     BACKENDS=torch TESTS=tests/core/test_render_grad.py CONSTRUCT=0 bash bench/device_check.sh
# Packages the GPU machine lacks travel as wheels in .whl/ (installed to /tmp/site).
set -o pipefail
OUT=${OUT:-/tmp/device_check}
mkdir -p "$OUT"
export PYTHONUNBUFFERED=1
if compgen -G ".whl/*.whl" >/dev/null; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
    --target /tmp/site .whl/*.whl && export PYTHONPATH=/tmp/site
fi
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader
python3 -c "import sys, torch, triton, numba, numpy; print(sys.version.split()[0], 'torch', torch.__version__, 'triton', triton.__version__, 'numba', numba.__version__, 'numpy', numpy.__version__)"
timeout ${RENDER_S:-240} python3 bench/render_bench.py --device cuda --sizes 1000000 --res 512 \
  --views 24 --repeat 10 --profile --backends ${BACKENDS:-torch torch-plain} \
  --json "$OUT/render.json" 2>&1 | tee "$OUT/render.log"
timeout ${TESTS_S:-240} python3 -m pytest -q -m gpu ${TESTS:-tests/core/test_render_grad.py tests/core/test_construct.py} \
  2>&1 | tee "$OUT/tests.log" | tail -15
[ "${CONSTRUCT:-1}" = 0 ] || timeout ${CONSTRUCT_S:-150} python3 bench/device_bench.py --devices cuda --out "$OUT" \
  --json "$OUT/device.json" 2>&1 | tail -12
