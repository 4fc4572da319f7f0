#!/bin/bash
# Device-side driver of the terrain fine-tuning (issue 13), in the mold of the lead's .loco/dev.sh:
#   bash stages/locomotion/scripts/gpu_terrain.sh TRAIN_S WORLDS EVAL_WORLDS EVAL_S FROM
# Run from the repository root on the GPU machine. Installs the staged wheels like dev.sh (a
# $HOME/stash bundle, or .whl/ for rsl-rl), trains with --terrain --arm-reach for TRAIN_S seconds
# (setup included), then exports the policy and evaluates it: loco-eval on the flat floor (issue
# 13's tracking figures must not regress) first, then loco-house (doorway with a 3 cm threshold and
# the layout stage's stairs) on the CPU with the time left. Results land in $OUT.
# FROM picks the start:
#   flat     start over from the committed flat-floor checkpoint (stages/locomotion/policies/g1_velocity),
#            ignoring any carried or earlier terrain checkpoint;
#   resume   (default) resume from the newest model_<iter>.pt of .loco/ckpt_terrain/ (carried from an
#            earlier machine) or of $HOME/ck_terrain (an earlier run on this one); else from the
#            committed terrain checkpoint (stages/locomotion/policies/g1_terrain), else the flat one.
# Every step says what it did; a failed or skipped step prints why (no silent failures).
R=$PWD
T0=$(date +%s)
. stages/locomotion/scripts/gpu_setup.sh || exit $?
CK=$HOME/ck_terrain
F=$([ "${5:-resume}" = flat ] && echo 1 || echo 0)
INIT=$(committed_init terrain $F)
start_in $CK $R/.loco/ckpt_terrain $F "$INIT" || exit $?
nvidia-smi -L
python3 -m stages.locomotion.cli train --terrain --arm-reach --num-worlds ${2:-4096} --iterations 100000 \
  --max-wall-s ${1:-380} --save-every 50 --print-every 10 --checkpoint-dir $CK \
  --init-from $INIT > $CK/stdout.log 2>&1
[ $? = 0 ] || echo "TRAINING FAILED (see the log tail below)"
tail -n 40 $CK/stdout.log
m=$(newest $CK); [ -n "$m" ] && cp $m $OUT/ && echo "checkpoint: $(basename $m)"
cp $CK/curve.csv $CK/train_config.json $OUT/ 2>/dev/null; tail -c 100000 $CK/locomotion.log > $OUT/locomotion.log
rm -rf $HOME/exp_terrain
python3 -m stages.locomotion.cli export --checkpoint-dir $CK --out $HOME/exp_terrain > /dev/null && \
  cp $HOME/exp_terrain/policy.pt $HOME/exp_terrain/policy.json $OUT/ || { echo "EXPORT FAILED"; exit 6; }
left() { echo $(( 585 - ($(date +%s) - T0) )); }
echo "loco-eval (flat floor) with $(left) s left"
timeout $(left) python3 -m stages.locomotion.cli eval --policy $HOME/exp_terrain \
  --num-worlds ${3:-100} --seconds ${4:-20} --json $OUT/eval.json 2> $OUT/eval.err
rc=$?; [ $rc = 0 ] || { echo "loco-eval FAILED (rc $rc; 124: out of time):"; tail -n 5 $OUT/eval.err; }
if [ $(left) -lt 60 ]; then
  echo "loco-house SKIPPED: $(left) s left; run it on the CPU elsewhere:" \
       "agentworld loco-house --policy <exported policy folder> --json house.json"
else
  echo "loco-house (CPU) with $(left) s left"
  timeout $(left) python3 -m stages.locomotion.cli house --device cpu --policy $HOME/exp_terrain \
    --json $OUT/house.json > $OUT/house.out 2> $OUT/house.err
  rc=$?
  if [ $rc = 0 ]; then tail -n 5 $OUT/house.out
  else echo "loco-house FAILED (rc $rc; 124: out of time): run it on the CPU elsewhere"; tail -n 5 $OUT/house.err; fi
fi
