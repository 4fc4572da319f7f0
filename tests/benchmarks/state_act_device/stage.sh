#!/usr/bin/env bash
# Device: keep the carried parts (.loco/parts/<letter>NN) in $HOME/stash; with all NW wheel parts there, install the
# wheels into $HOME/site; with all N parts of a bundle P (a spec P:N), unpack it: data bundles (a tar.xz of dataset
# folders, pack.sh) into $HOME/data, checkpoint bundles (prefix c: a tar of one ckpt_parts folder NAME) into
# $HOME/init/NAME, ready for train-policy --init.
# Usage: bash tests/benchmarks/state_act_device/stage.sh NW [P:N ...]   (or the older NW ND NE: bundles d and e)
mkdir -p $HOME/stash $HOME/data $HOME/init && cp .loco/parts/* $HOME/stash/ 2>/dev/null
nw=$(ls $HOME/stash/w* 2>/dev/null | wc -l); echo "wheel parts $nw of $1"
if [ "$nw" -ge "$1" ] && [ ! -f $HOME/site/.ok ]; then
  mkdir -p $HOME/stage && cat $HOME/stash/w* | tar -x -C $HOME/stage && \
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target $HOME/site $HOME/stage/wheels/*.whl && touch $HOME/site/.ok
  PYTHONPATH=$HOME/site:$PWD python3 -c "import lerobot, av, pydantic, datasets; print('imports ok', lerobot.__version__)"
fi
shift; specs=("$@"); [ $# -eq 2 ] && [[ "$1" != *:* ]] && specs=("d:$1" "e:$2")
for pn in "${specs[@]}"; do
  p=${pn%%:*}; n=${pn##*:}; k=$(ls $HOME/stash/$p[0-9]* 2>/dev/null | wc -l); echo "bundle $p: $k of $n"
  if [ "$n" -gt 0 ] && [ "$k" -ge "$n" ] && [ ! -f $HOME/data/.ok_$p ]; then
    if [ "$p" = c ]; then
      rm -rf $HOME/ckparts && mkdir -p $HOME/ckparts && cat $HOME/stash/c[0-9]* | tar -x -C $HOME/ckparts && \
      for d in $HOME/ckparts/*/; do PYTHONPATH=$HOME/site:$PWD python3 -m stages.policy.ckpt_parts unpack $d $HOME/init/$(basename $d); done && \
      touch $HOME/data/.ok_$p && ls $HOME/init/*
    else
      cat $HOME/stash/$p[0-9]* | xz -d | tar -x -C $HOME/data && touch $HOME/data/.ok_$p && du -sh $HOME/data/*
    fi
  fi
done
nvidia-smi --query-gpu=name,memory.used --format=csv,noheader
