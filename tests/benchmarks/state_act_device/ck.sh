#!/usr/bin/env bash
# Device: the last checkpoint of each named run as float16 parts in $OUT/NAME (<= 8 files per call in all: a
# dim-256 checkpoint is 3 files in 15 MiB parts; with one run named, its curve and summary files come too).
export PYTHONPATH=$HOME/site:$PWD
for n in "$@"; do
  c=$HOME/runs/$n/lerobot/checkpoints/last/pretrained_model
  [ -d $c ] || { echo "$n: no checkpoint at $c"; ls $HOME/runs/$n $HOME/runs/$n/lerobot/checkpoints 2>&1 | head; continue; }
  python3 -m stages.policy.ckpt_parts pack $c $OUT/$n --half && ls -la $OUT/$n
  [ $# -eq 1 ] && { cp $HOME/runs/$n/*.json $HOME/runs/$n/*.csv $OUT/$n/ 2>/dev/null; cp $HOME/runs/$n/agentworld_policy.json $OUT/$n/ 2>/dev/null; }; true
done
