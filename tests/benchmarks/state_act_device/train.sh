#!/usr/bin/env bash
# Device: start ACT runs in the background (setsid), one per spec "NAME|GPU|DATASET|SIZE|more train-policy args".
# SIZE 256: dim 256 / ff 1024 / 8 heads / lr 1e-4 (session 24's); 512: lerobot's default size at lr 5e-5.
# SEC: wall seconds per run. Usage: SEC=1000 bash tests/benchmarks/state_act_device/train.sh "p256|0|pick_dart|256|" ...
export PYTHONPATH=$HOME/site:$PWD PYTHONUNBUFFERED=1
mkdir -p $HOME/runs
for spec in "$@"; do
  IFS='|' read -r name gpu ds size more <<< "$spec"
  if [ "$size" = 512 ]; then
    lr=(--policy.optimizer_lr=5e-5 --policy.dim_model=512 --policy.dim_feedforward=3200 --policy.n_heads=8 --policy.latent_dim=32)
  else
    lr=(--policy.optimizer_lr=1e-4 --policy.dim_model=256 --policy.dim_feedforward=1024 --policy.n_heads=8 --policy.latent_dim=32)
  fi
  args=(); for a in "${lr[@]}"; do args+=("--lerobot-arg=$a"); done
  CUDA_VISIBLE_DEVICES=$gpu setsid nohup python3 -m pipeline.cli train-policy $HOME/data/$ds --policy act --cameras none \
    --state-drop base_x,base_y,base_theta --out $HOME/runs/$name --steps 100000 --batch-size 128 --device cuda \
    --num-workers 2 --max-seconds ${SEC:-1000} --save-freq 100000 --log-freq 500 "${args[@]}" $more \
    > $HOME/runs/$name.out 2>&1 < /dev/null &
  echo $! > $HOME/runs/$name.pid  # poll.sh waits on these (a pattern match would also find the calling shell)
  echo "started $name on GPU $gpu: $ds $size $more"
done
sleep 20; for f in $HOME/runs/*.pid; do kill -0 $(cat $f) 2>/dev/null && echo "$(basename $f .pid) running"; done
