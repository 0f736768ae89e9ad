#!/usr/bin/env bash
# What the GPU machine runs for the recorded results (benchmarks/results/, docs/validation/full_H200/):
# the test suite on CPU + CUDA, the full validation, the full scaling study.
#   OUT=dir bash benchmarks/gpu_session.sh [tests|validate|bench]...
set -uo pipefail
OUT=${OUT:?set OUT}
for part in "${@:-tests validate bench}"; do
  for step in $part; do
    case $step in
      tests) python3 -m pytest -q -p no:cacheprovider tests benchmarks > "$OUT/pytest.txt" 2>&1; tail -3 "$OUT/pytest.txt" ;;
      validate) python3 -m mdroll validate --full --device cuda --out "$OUT/validate_full" --no-progress > "$OUT/validate.txt" 2>&1; echo "validate rc=$?"; tail -25 "$OUT/validate.txt" ;;
      bench) python3 -m mdroll bench --full --out "$OUT/bench_full" --no-progress > "$OUT/bench.txt" 2>&1; echo "bench rc=$?"; tail -30 "$OUT/bench.txt" ;;
    esac
  done
done
