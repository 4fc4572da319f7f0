#!/bin/bash
# Device-side driver of the terrain fine-tuning (issue 13), in the mold of the lead's .loco/dev.sh:
#   bash stages/locomotion/scripts/gpu_terrain.sh TRAIN_S WORLDS EVAL_WORLDS EVAL_S
# Run from the repository root on the GPU machine. Installs the staged wheels like dev.sh (a
# $HOME/stash bundle, or .whl/ for rsl-rl), trains with --terrain --arm-reach starting from the
# committed flat-floor checkpoint (or resuming from $HOME/ck_terrain, or from .loco/ckpt_terrain/
# carried from an earlier machine), then exports the policy and evaluates it: loco-eval on the
# flat floor (issue 13's tracking figures must not regress) and loco-house on the CPU (doorway
# with a 3 cm threshold and the layout stage's stairs). Results land in $OUT.
R=$PWD
T0=$(date +%s)
if [ ! -d $HOME/site ]; then
  ls $HOME/stash/part0* >/dev/null 2>&1 || { echo "NO STASH"; exit 5; }
  (cd $HOME/stash && cat part0* | tar -x && python3 -m pip install -q --no-index --no-deps --no-compile \
     --no-cache-dir --target $HOME/site wheels/*.whl) || { echo SETUP FAILED; exit 3; }
fi
[ -d $HOME/site/rsl_rl ] || python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir \
   --target $HOME/site $R/.whl/*.whl || { echo WHEELS FAILED; exit 3; }
ERD=$R/.loco/erd; [ -d $ERD ] || ERD=
export PYTHONPATH=$HOME/site:$HOME/site/cmeel.prefix/lib/python3.12/site-packages:$R:$ERD
export WARP_CACHE_PATH=$HOME/stash/warp-cache PYTHONUNBUFFERED=1
CK=$HOME/ck_terrain; mkdir -p $CK; cp $R/.loco/ckpt_terrain/* $CK/ 2>/dev/null
nvidia-smi -L
python3 -m stages.locomotion.cli train --terrain --arm-reach --num-worlds ${2:-4096} --iterations 100000 \
  --max-wall-s ${1:-380} --save-every 50 --print-every 10 --checkpoint-dir $CK \
  --init-from $R/stages/locomotion/policies/g1_velocity/checkpoint.pt > $CK/stdout.log 2>&1
tail -n 40 $CK/stdout.log
m=$(ls $CK/model_*.pt 2>/dev/null | sort -t_ -k3 -n | tail -1); [ -n "$m" ] && cp $m $OUT/
cp $CK/curve.csv $CK/train_config.json $OUT/ 2>/dev/null; tail -c 100000 $CK/locomotion.log > $OUT/locomotion.log
python3 -m stages.locomotion.cli export --checkpoint-dir $CK --out $HOME/exp_terrain > /dev/null && \
  cp $HOME/exp_terrain/policy.pt $HOME/exp_terrain/policy.json $OUT/
timeout $(( 585 - ($(date +%s) - T0) )) python3 -m stages.locomotion.cli house --device cpu \
  --policy $HOME/exp_terrain --json $OUT/house.json | tail -n 5
timeout $(( 585 - ($(date +%s) - T0) )) python3 -m stages.locomotion.cli eval --policy $HOME/exp_terrain \
  --num-worlds ${3:-100} --seconds ${4:-20} --json $OUT/eval.json
