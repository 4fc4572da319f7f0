# Source from the repository root on the GPU machine (device tool) before a benchmark or GPU job:
#   . tests/benchmarks/gpu_env.sh && python3 tests/benchmarks/bench_engine.py --device cuda ...
#   . tests/benchmarks/gpu_env.sh && python3 -m pipeline.cli run jobs/demos_success_gpu.toml --no-progress
# Installs, once per machine, the simulation stack staged in $HOME/stash by ../shared/tools/device-wheels
# (six .carry/partNN calls), then the project's other missing wheels carried in .whl/ (lerobot, datasets,
# rsl-rl-lib, pydantic, rich, omniverse-asset-validator, ...: pip download --no-deps of constraints.txt's
# versions) and, when the image lacks PyAV (it does: carry .whl_av once, then .whl alone), .whl_av/.
# Sets PYTHONPATH (.loco/erd when carried: the G1's URDF and the Panda description, which the demos job
# and bench_engine need there: carry .loco), WARP_CACHE_PATH and unbuffered output. Says what it could
# not do; returns non-zero then. On a host of 4 GPUs: jobs/demos_success_gpu4.toml (one kitchen per GPU).
# Device calls: a call that does not name a carried path removes it on the machine, also under a job still
# running in the background: every poll call of such a job carries the same paths (.loco, .benchdata, ...).
# .benchdata/cat (bench_engine's catalog, built here) holds absolute paths of this checkout (/work/main), which
# is also the repository root there. A lease ends at 30 minutes of the session's held time: copy checkpoints
# to $OUT in every call.
_aw_fail() { echo "gpu_env: $*" >&2; return 3; }
if [ ! -d "$HOME/site" ]; then
  ls "$HOME"/stash/part0* >/dev/null 2>&1 || { _aw_fail "no staged wheels in \$HOME/stash (the .carry/partNN calls)"; return 3; }
  (cd "$HOME/stash" && cat part0* | tar -x && python3 -m pip install -q --no-index --no-deps --no-compile \
     --no-cache-dir --target "$HOME/site" wheels/*.whl) >/dev/null 2>&1 || { _aw_fail "installing the staged wheels failed"; return 3; }
fi
# .whl/ and .loco/erd may instead be staged once on the machine ($HOME/stash/whl, $HOME/erd: one call each,
# `cp -r .whl $HOME/stash/whl`, `cp -r .loco/erd $HOME/erd`), so later calls need not carry them beside a larger tree.
_aw_whl=.whl; [ -d "$_aw_whl" ] || _aw_whl="$HOME/stash/whl"
_aw_erd="$PWD/.loco/erd"; [ -d "$_aw_erd" ] || _aw_erd="$HOME/erd"
if [ -d "$_aw_whl" ] && [ ! -f "$HOME/site/.aw_whl" ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target "$HOME/site" "$_aw_whl"/*.whl \
    >/dev/null 2>&1 && touch "$HOME/site/.aw_whl" || { _aw_fail "installing .whl/ failed"; return 3; }
fi
if ! python3 -c "import av" 2>/dev/null && [ -d .whl_av ]; then
  python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --target "$HOME/site" .whl_av/*.whl \
    >/dev/null 2>&1 || { _aw_fail "installing .whl_av/ failed"; return 3; }
fi
export PYTHONPATH="$HOME/site:$HOME/site/cmeel.prefix/lib/python3.12/site-packages:$PWD${PYTHONPATH:+:$PYTHONPATH}"
[ -d "$_aw_erd" ] && export PYTHONPATH="$PYTHONPATH:$_aw_erd"
# The third-party robots the hands / dual-arm tasks read (../shared/assets is not on the GPU machine): carry
# .carry_assets (tar -C ../shared/assets -cf .carry_assets/robots.tar robots/<the robots> README.md) once.
if [ -f .carry_assets/robots.tar ] && [ ! -d "$HOME/shared_assets/robots" ]; then
  mkdir -p "$HOME/shared_assets" && tar -C "$HOME/shared_assets" -xf .carry_assets/robots.tar \
    || _aw_fail "unpacking .carry_assets/robots.tar failed"
fi
[ -d "$HOME/shared_assets/robots" ] && export AGENTWORLD_SHARED_ASSETS="$HOME/shared_assets"
# greenlet (the engine's expert programs) is not in the staged wheels: in .loco/erd (or $HOME/erd), copied once.
[ -d "$_aw_erd/greenlet" ] && [ ! -d "$HOME/site/greenlet" ] && cp -r "$_aw_erd/greenlet" "$HOME/site/"
export WARP_CACHE_PATH="$HOME/stash/warp-cache" PYTHONUNBUFFERED=1
python3 -c "import newton, warp, lerobot, pydantic" 2>/dev/null || { _aw_fail "newton/warp/lerobot/pydantic do not import"; return 3; }
