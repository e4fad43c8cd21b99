#!/usr/bin/env bash
# Every validation-side check a model change is judged by (never the test splits), two
# at a time, each into its own file under OUT:
#   benchmarks/tried/eval_bundle.sh MODEL_DIR OUT [JOBS]
# Run with the sources to judge on PYTHONPATH (a tracker change lives in the kernel, not
# in the model's settings) and a NUMBA_CACHE_DIR of their own. About 10 minutes on two
# cores. Checks: validation_check.py positions, +speed, +speed+heading; fault_age_recall.py
# (five fault draws, positions and every column variant: the figures to judge cells by, since
# one draw hid a 0.5 Hz loss, docs/deviations.md); simulated_check.py;
# tried/gnss_validation.py; tried/hangover_check.py over the five seed pairs at 10, 5,
# 1, 0.5 Hz and eight more at 1, 0.5 Hz (the pairs of docs/deviations.md); and
# tried/variant_errors.py on DrivePlotR with speed and heading; where the first clean
# fixes after a fault are flagged (tried/hangover_check.py --by-ended, 1 Hz simulated and
# the validation drives) and after which protocol gnss episodes the false positives sit
# (tried/gnss_validation.py --after): a tracker change is judged on gnss before training.
set -euo pipefail
model=$1 out=$2 jobs=${3:-2}
here=$(cd "$(dirname "$0")/.." && pwd)
mkdir -p "$out"
{
  echo "validation_positions python $here/validation_check.py --model $model"
  echo "validation_speed python $here/validation_check.py --model $model --variant +speed"
  echo "validation_speed_heading python $here/validation_check.py --model $model --variant +speed+heading"
  echo "draws5 python $here/fault_age_recall.py --model $model --variant positions --variant +speed --variant +speed+heading"
  echo "simulated python $here/simulated_check.py --model $model"
  echo "gnss python $here/tried/gnss_validation.py --model $model"
  echo "variant_errors python $here/tried/variant_errors.py --model $model"
  echo "byended python $here/tried/hangover_check.py --model $model --rates 1 --by-ended 5"
  echo "gnss_after python $here/tried/gnss_validation.py --model $model --after"
  for pair in 4242/0 7/1 555/1 99/1 555/0; do
    echo "hangover_${pair/\//_} python $here/tried/hangover_check.py --model $model --rates 10,5,1,0.5 --sim-seed ${pair%/*} --inject-seed ${pair#*/}"
  done
  for pair in 11/2 123/3 2024/4 31/5 808/6 4242/7 9/8 77/9; do
    echo "hangover8_${pair/\//_} python $here/tried/hangover_check.py --model $model --rates 1,0.5 --sim-seed ${pair%/*} --inject-seed ${pair#*/} --simulated-only"
  done
} | xargs -P "$jobs" -L 1 sh -c 'name=$0; "$@" > "'"$out"'/$name.txt" 2>&1'
echo "wrote $out"
