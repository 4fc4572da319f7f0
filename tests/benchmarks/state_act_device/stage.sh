#!/usr/bin/env bash
# Device: keep the carried parts (.loco/parts/{w,d,e}NN) in $HOME/stash; with all NW wheel parts there,
# install the wheels into $HOME/site; with all parts of a data bundle (ND for d, NE for e), unpack it into $HOME/data.
# Usage: bash tests/benchmarks/state_act_device/stage.sh NW ND NE
mkdir -p $HOME/stash $HOME/data && cp .loco/parts/[wde]* $HOME/stash/ 2>/dev/null
nw=$(ls $HOME/stash/w* 2>/dev/null | wc -l); echo "wheel parts $nw of $1"
if [ "$nw" -ge "$1" ] && [ ! -f $HOME/site/.ok ]; then
  mkdir -p $HOME/stage && cat $HOME/stash/w* | tar -x -C $HOME/stage && \
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target $HOME/site $HOME/stage/wheels/*.whl && touch $HOME/site/.ok
  PYTHONPATH=$HOME/site:$PWD python3 -c "import lerobot, av, pydantic, datasets; print('imports ok', lerobot.__version__)"
fi
for pn in d:$2 e:$3; do
  p=${pn%%:*}; n=${pn##*:}; k=$(ls $HOME/stash/$p* 2>/dev/null | wc -l); echo "bundle $p: $k of $n"
  if [ "$n" -gt 0 ] && [ "$k" -ge "$n" ] && [ ! -f $HOME/data/.ok_$p ]; then
    cat $HOME/stash/$p* | xz -d | tar -x -C $HOME/data && touch $HOME/data/.ok_$p && du -sh $HOME/data/*
  fi
done
nvidia-smi --query-gpu=name,memory.used --format=csv,noheader
