#!/usr/bin/env bash
# Here, from the repository root: the training wheels as one tar split into parts .loco/parts/wNN (lerobot and what it
# needs beyond the GPU image, from tests/benchmarks/gpu_wheels.sh's .whl/ and .whl_av/: 47 MB in 4 parts), and
# datasets (args) as one tar.xz split into parts .loco/parts/<PREFIX>NN (a 400-episode state set: ~12 MB), 14 MB
# each: a device call carries the tree plus one part (session 26: 52.6 + 10 MB went, 52.6 + 14 MB was refused; the tree
# is ~45 MB since then).
# Session 25's device recipe for no-camera ACT (README, issue 17), calls back to back (a machine idle 30 s goes back):
#   stage.sh per part (carry one part each), then train.sh, poll.sh (<= 580 s a call), ck.sh (<= 8 files a call).
# Usage: pack.sh wheels | pack.sh PREFIX DATASET_DIR...  (PREFIX d, e, ...: one bundle each)
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"
mkdir -p .loco/parts /tmp/state_act_stage
if [ "$1" = wheels ]; then
  rm -rf /tmp/state_act_stage/wheels .loco/parts/w*; mkdir -p /tmp/state_act_stage/wheels
  for f in .whl/*.whl .whl_av/*.whl; do  # the GPU image has these (or training does not need them)
    case $(basename $f | cut -d- -f1 | tr A-Z a-z) in
      tensorboard|tensorboard_data_server|markdown|werkzeug|pygments|rich|markdown_it_py|mdurl|tqdm|einops|greenlet|\
      rsl_rl_lib|gitpython|gitdb|smmap|cloudpickle|omniverse_asset_validator) ;;
      *) cp $f /tmp/state_act_stage/wheels/ ;;
    esac
  done
  tar -C /tmp/state_act_stage -cf - wheels | split -b 14000000 -d - .loco/parts/w
else
  p=$1; shift; rm -f .loco/parts/$p*
  args=(); for d in "$@"; do args+=(-C "$(dirname $d)" "$(basename $d)"); done
  tar -cf - "${args[@]}" | xz -T2 -6 | split -b 14000000 -d - .loco/parts/$p
fi
ls -la .loco/parts
