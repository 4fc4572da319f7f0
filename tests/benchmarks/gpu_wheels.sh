#!/usr/bin/env bash
# Here (not on the GPU machine), from the repository root: download the wheels that the GPU image lacks
# beside ../shared/tools/device-wheels' simulation stack, at constraints.txt's versions, into .whl/
# (~15 MB: lerobot, datasets, rsl-rl-lib, pydantic, rich, omniverse-asset-validator, ...) and .whl_av/
# (PyAV, ~39 MB; carried only where the image has no `av`). Both folders are git-ignored; name them in
# the device call's carry, then `. tests/benchmarks/gpu_env.sh` there installs them.
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"
for d in /.whl/ /.whl_av/ /.loco/ /.benchdata/; do grep -qxF "$d" .git/info/exclude || echo "$d" >> .git/info/exclude; done
pkgs=()
for p in rsl-rl-lib tensordict pyvers GitPython gitdb smmap cloudpickle datasets multiprocess dill lerobot termcolor \
         gymnasium Farama-Notifications draccus toml mergedeep omniverse-asset-validator xxhash typing-inspect \
         mypy_extensions pydantic pydantic_core annotated-types typing-inspection rich markdown-it-py mdurl Pygments \
         tqdm jsonlines einops tensorboard tensorboard-data-server Markdown Werkzeug greenlet av; do
  v=$(grep -i "^$p==" constraints.txt) || { echo "gpu_wheels: $p is not in constraints.txt" >&2; exit 2; }
  pkgs+=("$v")
done
rm -rf .whl .whl_av && mkdir -p .whl .whl_av
python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
  --platform manylinux_2_34_x86_64 --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 \
  --platform manylinux_2_17_x86_64 --platform manylinux2014_x86_64 --platform manylinux1_x86_64 \
  -d .whl "${pkgs[@]}" 2>&1 | grep -v 'is ignored' || true
mv .whl/av-*.whl .whl_av/
# the G1's URDF (geometry is not needed: training strips it) for the locomotion runs
erd=$(.venv/bin/python -c "from stages.locomotion.robot import g1_urdf_path; print(g1_urdf_path())")
dst=.loco/erd/cmeel.prefix/share/example-robot-data/robots/g1_description/urdf
mkdir -p "$dst" && cp "$erd" "$dst/"
# the Panda description (URDF and meshes, 11 MB), found on sys.path by stages.simulate.robot there
pan=$(.venv/bin/python -c "from stages.simulate.robot import _pip_panda_root; print(_pip_panda_root())")
rm -rf .loco/erd/cmeel.prefix/share/example-robot-data/robots/panda_description
cp -r "$pan/robots/panda_description" .loco/erd/cmeel.prefix/share/example-robot-data/robots/
du -sh .whl .whl_av .loco/erd
# the third-party robots of the hands / dual-arm tasks (gpu_env.sh unpacks them, AGENTWORLD_SHARED_ASSETS)
mkdir -p .carry_assets && tar -C ../shared/assets -cf .carry_assets/robots.tar robots/aloha__gym_aloha \
  robots/allegro_hand__robotlocomotion robots/shadow_hand__gymnasium_robotics robots/robotiq_2f85__menagerie \
  robots/fetch__gymnasium_robotics README.md
du -sh .carry_assets
