# Sourced by the device-side locomotion drivers (gpu_terrain.sh, gpu_h1.sh) from the repository root on
# the GPU machine: installs, once per machine, the simulation stack staged in $HOME/stash
# (../shared/tools/device-wheels) and the carried .whl/ (rsl-rl-lib and the project's other wheels), sets
# PYTHONPATH (.loco/erd when carried: the G1's URDF), WARP_CACHE_PATH and unbuffered output, and defines
# `newest DIR` (the model_<iter>.pt of DIR with the highest iteration). Returns non-zero, saying why, when
# a step fails.
R=$PWD
if [ ! -d $HOME/site ]; then
  ls $HOME/stash/part0* >/dev/null 2>&1 || { echo "NO STASH"; return 5; }
  (cd $HOME/stash && cat part0* | tar -x && python3 -m pip install -q --no-index --no-deps --no-compile \
     --no-cache-dir --target $HOME/site wheels/*.whl) || { echo SETUP FAILED; return 3; }
fi
[ -d $HOME/site/rsl_rl ] || python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir \
   --target $HOME/site $R/.whl/*.whl || { echo WHEELS FAILED; return 3; }
ERD=$R/.loco/erd; [ -d $ERD ] || ERD=
export PYTHONPATH=$HOME/site:$HOME/site/cmeel.prefix/lib/python3.12/site-packages:$R:$ERD
export WARP_CACHE_PATH=$HOME/stash/warp-cache PYTHONUNBUFFERED=1
newest() { ls $1/model_*.pt 2>/dev/null | sed 's/.*model_\([0-9]*\)\.pt$/\1 &/' | sort -n | tail -1 | cut -d' ' -f2; }
# `start_in CK CARRIED FRESH WHAT`: the checkpoint folder CK for this run. FRESH=1 empties it (a run
# from WHAT); otherwise the carried folder CARRIED (an earlier machine's checkpoints, when present) is
# copied in and the newest model_<iter>.pt there is where training resumes (WHAT when there is none).
start_in() {
  if [ "$3" = 1 ]; then
    rm -rf $1; mkdir -p $1; echo "start: $4 (fresh)"; return 0
  fi
  mkdir -p $1
  if [ -d $2 ]; then cp $2/* $1/ || { echo "COPY OF $2 FAILED"; return 4; }; fi
  chmod -R u+w $1
  local m; m=$(newest $1); echo "start: ${m:-$4 (no checkpoint carried or left here)}"
}
# `committed_init RUN FRESH`: the committed checkpoint a RUN (terrain | h1) starts from when no carried or
# earlier checkpoint is there: terrain: policies/g1_terrain, else (or FRESH=1) the flat policies/g1_velocity;
# h1: policies/h1_velocity, or nothing (a fresh policy) with FRESH=1 or when none is committed.
committed_init() {
  local P=$R/stages/locomotion/policies
  case $1 in
    terrain) if [ "$2" != 1 ] && [ -f $P/g1_terrain/checkpoint.pt ]; then echo $P/g1_terrain/checkpoint.pt
             else echo $P/g1_velocity/checkpoint.pt; fi;;
    h1) [ "$2" != 1 ] && [ -f $P/h1_velocity/checkpoint.pt ] && echo $P/h1_velocity/checkpoint.pt;;
  esac
  return 0
}
