#!/bin/bash
# Device-side driver of the H1's flat-floor velocity training from scratch (issue 13, humanoids):
#   bash stages/locomotion/scripts/gpu_h1.sh TRAIN_S WORLDS EVAL_WORLDS EVAL_S FROM
# Run from the repository root on the GPU machine. Installs the staged wheels like gpu_terrain.sh (a
# $HOME/stash bundle, or .whl/ for rsl-rl), trains `loco-train --robot h1` on flat floors for
# TRAIN_S seconds (setup included), then exports the policy and evaluates it with loco-eval (flat
# floor, EVAL_WORLDS rollouts of EVAL_S s) with the time left. Results land in $OUT: the newest
# model_<iter>.pt, curve.csv, train_config.json, policy.pt, policy.json, eval.json, locomotion.log.
# The H1 model: its MJCF (13 kB; the meshes are not needed, the trainer drops them) from
# $AGENTWORLD_SHARED_ASSETS, else .loco/assets (carry it), else ../shared/assets; set it up with
#   mkdir -p .loco/assets/robots/unitree_h1__newton_assets/mjcf && cp ../shared/assets/robots/\
#   unitree_h1__newton_assets/mjcf/h1.xml .loco/assets/robots/unitree_h1__newton_assets/mjcf/
# FROM picks the start:
#   scratch  a fresh policy, ignoring any carried or earlier H1 checkpoint;
#   resume   (default) resume from the newest model_<iter>.pt of .loco/ckpt_h1/ (carried from an
#            earlier machine: copy $OUT's model_<iter>.pt and curve.csv there between calls) or of
#            $HOME/ck_h1 (an earlier run on this one); else the committed checkpoint
#            (stages/locomotion/policies/h1_velocity); a fresh policy when there is none.
# Every step says what it did; a failed or skipped step prints why (no silent failures).
R=$PWD
T0=$(date +%s)
. stages/locomotion/scripts/gpu_setup.sh || exit $?
MJCF=robots/unitree_h1__newton_assets/mjcf/h1.xml
if [ -z "$AGENTWORLD_SHARED_ASSETS" ]; then
  for d in $R/.loco/assets $R/../shared/assets; do [ -f $d/$MJCF ] && export AGENTWORLD_SHARED_ASSETS=$d && break; done
fi
[ -f "$AGENTWORLD_SHARED_ASSETS/$MJCF" ] || { echo "NO H1 MJCF: carry .loco/assets/$MJCF (see the header)"; exit 7; }
echo "H1 model: $AGENTWORLD_SHARED_ASSETS/$MJCF"
CK=$HOME/ck_h1
F=$([ "${5:-resume}" = scratch ] && echo 1 || echo 0)
INIT=$(committed_init h1 $F)
start_in $CK $R/.loco/ckpt_h1 $F "${INIT:-a fresh policy}" || exit $?
nvidia-smi -L
python3 -m stages.locomotion.cli train --robot h1 --num-worlds ${2:-4096} --iterations 100000 \
  --max-wall-s ${1:-420} --save-every 50 --print-every 10 --checkpoint-dir $CK ${INIT:+--init-from $INIT} > $CK/stdout.log 2>&1
[ $? = 0 ] || echo "TRAINING FAILED (see the log tail below)"
tail -n 40 $CK/stdout.log
m=$(newest $CK); [ -n "$m" ] && cp $m $OUT/ && echo "checkpoint: $(basename $m)"
cp $CK/curve.csv $CK/train_config.json $OUT/ 2>/dev/null; tail -c 100000 $CK/locomotion.log > $OUT/locomotion.log
rm -rf $HOME/exp_h1
python3 -m stages.locomotion.cli export --checkpoint-dir $CK --out $HOME/exp_h1 > /dev/null && \
  cp $HOME/exp_h1/policy.pt $HOME/exp_h1/policy.json $OUT/ || { echo "EXPORT FAILED"; exit 6; }
left() { echo $(( 585 - ($(date +%s) - T0) )); }
if [ $(left) -lt 40 ]; then
  echo "loco-eval SKIPPED: $(left) s left; run: agentworld loco-eval --policy <exported folder> --json eval.json"
  exit 0
fi
echo "loco-eval (flat floor) with $(left) s left"
timeout $(left) python3 -m stages.locomotion.cli eval --policy $HOME/exp_h1 \
  --num-worlds ${3:-100} --seconds ${4:-20} --json $OUT/eval.json 2> $OUT/eval.err
rc=$?; [ $rc = 0 ] || { echo "loco-eval FAILED (rc $rc; 124: out of time):"; tail -n 5 $OUT/eval.err; }
