#!/bin/bash
# Device-side driver for long locomotion training in the background (issue 13): the G1 terrain
# fine-tune and the H1 flat-floor run side by side on one GPU, over several calls of one machine.
#   bash stages/locomotion/scripts/gpu_bg.sh start WALL_S [fresh]   # install, start both, return
#   bash stages/locomotion/scripts/gpu_bg.sh poll  WAIT_S           # wait, copy newest checkpoints to $OUT
#   bash stages/locomotion/scripts/gpu_bg.sh end   LIMIT_S          # stop, export, loco-eval both
# Every call of one machine must carry the same paths (.whl and .loco: the G1 URDF in .loco/erd and
# the H1 MJCF in .loco/assets are read while the models build). `start` resumes each run from its
# carried .loco/ckpt_<run>/ (checkpoints saved from earlier $OUT), else from the committed policies
# (g1_terrain / h1_velocity checkpoint.pt), else from the flat G1 policy / a fresh H1; `fresh`
# ignores carried and committed checkpoints. `poll` copies 6 files (the result limit counts files);
# `end` writes one res.tgz (exported policies, curves, eval.json per run). Session 17 used it for
# 2 x 1,400 s on an H100: G1 terrain 3,308 -> 4,613 and H1 1,573 -> 3,448 PPO iterations.
# TERRAIN_ARGS / H1_ARGS (environment of `start`) are appended to each run's loco-train line (e.g. "--track-ang-vel 2 --terrain-kinds 0.5,0.2,0.3", "--tracking-std 0.35").
R=$PWD
case "$1" in
start)
  . stages/locomotion/scripts/gpu_setup.sh || exit $?
  export AGENTWORLD_SHARED_ASSETS=$R/.loco/assets
  nvidia-smi -L
  F=0; [ "$3" = fresh ] && F=1
  IG=$(committed_init terrain $F); IH=$(committed_init h1 $F)
  start_in $HOME/ck_terrain $R/.loco/ckpt_terrain $F "$IG" || exit $?
  start_in $HOME/ck_h1 $R/.loco/ckpt_h1 $F "${IH:-a fresh policy}" || exit $?
  setsid nohup python3 -m stages.locomotion.cli train --terrain --arm-reach --num-worlds 4096 --iterations 100000 \
    --max-wall-s ${2:-1400} --save-every 50 --print-every 10 --checkpoint-dir $HOME/ck_terrain \
    --init-from $IG $TERRAIN_ARGS > $HOME/ck_terrain/stdout.log 2>&1 < /dev/null &
  echo $! > $HOME/terrain.pid
  setsid nohup python3 -m stages.locomotion.cli train --robot h1 --num-worlds 4096 --iterations 100000 \
    --max-wall-s ${2:-1400} --save-every 50 --print-every 10 --checkpoint-dir $HOME/ck_h1 \
    ${IH:+--init-from $IH} $H1_ARGS > $HOME/ck_h1/stdout.log 2>&1 < /dev/null &
  echo $! > $HOME/h1.pid
  echo "started terrain $(cat $HOME/terrain.pid), h1 $(cat $HOME/h1.pid)";;
poll)
  . stages/locomotion/scripts/gpu_setup.sh || exit $?
  for i in $(seq 1 $((${2:-500} / 20))); do sleep 20; done
  for r in terrain h1; do
    mkdir -p $OUT/$r; m=$(newest $HOME/ck_$r)
    [ -n "$m" ] && cp $m $OUT/$r/ && echo "$r checkpoint: $(basename $m)"
    cp $HOME/ck_$r/curve.csv $HOME/ck_$r/train_config.json $OUT/$r/ 2>/dev/null
    kill -0 $(cat $HOME/$r.pid) 2>/dev/null && echo "$r running" || { echo "$r ENDED:"; tail -n 5 $HOME/ck_$r/stdout.log; }
  done;;
end)
  . stages/locomotion/scripts/gpu_setup.sh || exit $?
  export AGENTWORLD_SHARED_ASSETS=$R/.loco/assets
  T0=$(date +%s); LIM=${2:-230}; left() { echo $(( LIM - ($(date +%s) - T0) )); }
  for r in terrain h1; do kill $(cat $HOME/$r.pid) 2>/dev/null; done; sleep 5
  RES=$HOME/res; rm -rf $RES
  for r in terrain h1; do
    mkdir -p $RES; echo "$r newest: $(basename $(newest $HOME/ck_$r))"
    python3 -m stages.locomotion.cli export --checkpoint-dir $HOME/ck_$r --out $RES/$r > $RES/$r.export.out 2>&1 \
      || { echo "$r EXPORT FAILED"; tail -n 3 $RES/$r.export.out; }
  done
  for r in terrain h1; do
    [ $(left) -lt 20 ] && { echo "$r loco-eval SKIPPED: $(left) s left"; continue; }
    echo "$r loco-eval with $(left) s left"
    timeout $(left) python3 -m stages.locomotion.cli eval --policy $RES/$r --num-worlds 100 --seconds 20 \
      --json $RES/$r/eval.json > $RES/$r/eval.out 2> $RES/$r/eval.err
    echo "rc $? (124: out of time)"; cat $RES/$r/eval.json 2>/dev/null; echo
  done
  (cd $HOME && tar -czf $OUT/res.tgz res) && ls -la $OUT;;
*) echo "usage: gpu_bg.sh start WALL_S [fresh] | poll WAIT_S | end LIMIT_S"; exit 2;;
esac
