#!/usr/bin/env bash
# One prepared run for a machine with an NVIDIA GPU (docs/sph.md, "GPU" and "The 3D solver on
# the GPU"), most important first, each step with its own time limit, everything it writes
# under $OUT (default ./gpu_session_out):
#   1. the GPU, Numba and numba-cuda it sees;
#   2. the GPU tests of the 2D and 3D solvers on the device (TERRADYN_GPU_TEST=device);
#   3. the 3D benchmark (GPU vs CPU, ms/step, minutes per leg run) and the 2D one;
#   4. 3D legs on the GPU (the leg target's runs) while the session is under BUDGET_S seconds.
# Run from the repository root with python3 that has numpy, scipy, pandas, xarray, typer,
# rich, matplotlib, numba, numba-cuda and pytest (PYTHONPATH may name a folder of wheels
# unpacked with pip --target, see docs/sph.md). Usage:
#   OUT=/path LEG_DX_MM=3 BUDGET_S=540 bash benchmarks/gpu_session.sh
set -u
OUT=${OUT:-gpu_session_out}
LEG_DX_MM=${LEG_DX_MM:-3}
BUDGET_S=${BUDGET_S:-540}
mkdir -p "$OUT"
export PYTHONPATH=${PYTHONPATH:+$PYTHONPATH:}src MPLBACKEND=Agg
start=$(date +%s)
step() { echo "== $* ($(($(date +%s) - start)) s)" | tee -a "$OUT/log.txt" >&2; }

step "1. environment"
nvidia-smi > "$OUT/nvidia-smi.txt" 2>&1
python3 -c "import numba, numba_cuda; from numba import cuda; print(numba.__version__, numba_cuda.__version__, cuda.is_available()); cuda.detect()" \
  > "$OUT/numba.txt" 2>&1 || { step "numba-cuda or the GPU is missing: see $OUT/numba.txt"; exit 1; }

step "2. GPU tests on the device"
TERRADYN_GPU_TEST=device timeout 420 python3 -m pytest -q -p no:cacheprovider \
  tests/test_sph_gpu.py tests/test_sph_gpu3d.py > "$OUT/tests.txt" 2>&1
echo "tests rc $?" >> "$OUT/log.txt"

step "3. benchmarks"
timeout 300 python3 benchmarks/bench_sph_gpu3d.py --out "$OUT/sph_gpu3d.json" > "$OUT/bench_gpu3d.txt" 2>&1
echo "bench_sph_gpu3d rc $?" >> "$OUT/log.txt"
timeout 240 python3 benchmarks/bench_sph_gpu.py > "$OUT/bench_gpu.txt" 2>&1
echo "bench_sph_gpu rc $?" >> "$OUT/log.txt"
cp benchmarks/results/sph_gpu.json "$OUT/" 2>/dev/null

step "4. 3D legs at ${LEG_DX_MM} mm on the GPU"
for medium in "poppy LP" "0.3 mm glass CP"; do
  for leg in flat c reverse-c; do
    left=$((BUDGET_S - ($(date +%s) - start)))
    [ "$left" -gt 30 ] || { step "budget spent"; break 2; }
    tag="${leg}_${medium// /_}_${LEG_DX_MM}mm"
    step "leg3d $tag (at most $left s)"
    timeout "$left" python3 -m terradyn sph leg3d --backend gpu --medium "$medium" --leg "$leg" \
      --dx-mm "$LEG_DX_MM" -o "$OUT/leg3d_$tag.json" > "$OUT/leg3d_$tag.txt" 2>&1
    echo "leg3d $tag rc $?" >> "$OUT/log.txt"
  done
done
step "done"
