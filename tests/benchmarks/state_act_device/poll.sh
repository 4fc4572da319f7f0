#!/usr/bin/env bash
# Device: wait up to $1 s (checked every 30 s) for the runs train.sh started, printing each run's last progress line; copies logs to $OUT.
end=$((SECONDS + ${1:-280}))
while [ $SECONDS -lt $end ]; do
  sleep 30
  n=0; for f in $HOME/runs/*.pid; do kill -0 $(cat $f) 2>/dev/null && n=$((n + 1)); done
  [ "$n" -eq 0 ] && break  # (by pid: session 27's `pgrep -f train-policy` matched its own calling shell)
done
for f in $HOME/runs/*.out; do echo "== $(basename $f) $(tr '\r' '\n' < $f | grep -a 'INFO.*step:' | tail -1 | cut -c1-200)"; tr '\r' '\n' < $f | grep -a -i "error\|Traceback\|train-policy:" | tail -2; done
nvidia-smi --query-gpu=utilization.gpu,memory.used --format=csv,noheader
mkdir -p $OUT/logs && cp $HOME/runs/*.out $OUT/logs/ 2>/dev/null; for d in $HOME/runs/*/; do n=$(basename $d); cp $d/train.log $OUT/logs/$n.train.log 2>/dev/null; cp $d/*.json $OUT/logs/ 2>/dev/null; done; true
