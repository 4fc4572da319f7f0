"""A lerobot policy run for many worlds at once, each world with its own episode clock.

lerobot's ``select_action`` keeps one action queue (or one temporal ensemble, one observation
history) for its whole batch: every batch element must start its episode together. Worlds of the
batched engine start and end episodes at different times, so :class:`BatchedRunner` keeps that
state per world and batches only the network: one preprocessor call for the worlds that act at a
step and one model call for those that need a new chunk. Per world it does exactly what lerobot's
``select_action`` does for a batch of one (tests compare the two):

- ACT with temporal ensembling (``temporal_ensemble_coeff`` set, ``n_action_steps`` 1): a chunk
  per step for every acting world, each world's own ``ACTTemporalEnsembler`` (lerobot's class);
- ACT without: a queue of ``n_action_steps`` actions per world, refilled from a new chunk when empty;
- Diffusion Policy: a history of ``n_obs_steps`` observations per world (the first one repeated at
  an episode's start) and a queue of ``n_action_steps`` actions, refilled as lerobot's
  ``generate_actions`` does, with every random number (the initial noise and the DDPM steps') from
  the world's own generator (seeded by the episode seed), so a world's actions do not depend on the
  others.

Observations are what the dataset's frames hold: ``observation.state`` (S,) float32, for a policy
trained with it ``observation.environment_state`` (D,) float32 (lerobot's ENV input) and, per policy
camera, ``observation.images.<camera>`` RGB uint8 (H, W, 3), given to the policy as float32
(3, H, W) in [0, 1] as ``LeRobotDataset`` gives decoded video frames. Actions come back unnormalized
by the checkpoint's postprocessor, float32 (A,) in the dataset's action layout.
"""

from __future__ import annotations

import os
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

STATE = "observation.state"
ENV_STATE = "observation.environment_state"  # optional: the task objects' state (stages.engine.env_state)
IMAGES = "observation.images"  # lerobot's stacked-camera key (OBS_IMAGES)
SUPPORTED = ("act", "diffusion")
POLICY_INFO = "agentworld_policy.json"
"""beside a checkpoint's config.json: ``{"state": [names of observation.state's entries],
"environment_state": [names] or []}`` from the training dataset (written by train-policy)."""


def write_policy_info(checkpoint: Path, dataset: Path) -> Path:
    """Write :data:`POLICY_INFO` into the ``pretrained_model`` folder ``checkpoint`` from the
    training ``dataset``'s feature names (``meta/info.json``)."""
    import json

    from stages.dataset.view import feature_names

    info = {"state": feature_names(dataset, STATE) or [], "environment_state": feature_names(dataset, ENV_STATE) or []}
    path = Path(checkpoint) / POLICY_INFO
    path.write_text(json.dumps(info, indent=2) + "\n")
    return path


def read_policy_info(checkpoint: Path, state_dim: int,
                     env_state_dim: int = 0) -> tuple[tuple[str, ...] | None, tuple[str, ...] | None]:
    """The ``(state, environment_state)`` names of :data:`POLICY_INFO` in ``checkpoint`` (each None
    without the file or when it names none); ValueError (one line, naming the file) when it is
    unreadable or a list does not match the policy's input size."""
    import json

    path = Path(checkpoint) / POLICY_INFO
    if not path.is_file():
        return None, None
    try:
        info = json.loads(path.read_text())
        names = tuple(str(n) for n in info["state"])
        env = tuple(str(n) for n in info.get("environment_state") or ())
    except (KeyError, TypeError, AttributeError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: unreadable ({e})") from None
    if names and len(names) != state_dim:
        raise ValueError(f"{path}: {len(names)} state names for a policy state of {state_dim} entries")
    if env and len(env) != env_state_dim:
        raise ValueError(f"{path}: {len(env)} environment-state names for a policy environment state of "
                         f"{env_state_dim} entries")
    return names or None, env or None


@dataclass(eq=False)
class LoadedPolicy:
    """A checkpoint loaded for inference: the policy (eval mode, on ``device``), its pre- and
    postprocessor pipelines, its type, camera keys (``observation.images.<camera>``) with their
    (3, H, W) shapes, and the state and action sizes."""

    policy: Any
    preprocessor: Any
    postprocessor: Any
    type: str
    device: str
    image_shapes: dict[str, tuple[int, int, int]]
    state_dim: int
    action_dim: int
    env_state_dim: int = 0
    """size of the policy's ``observation.environment_state`` input (0: it takes none)"""
    state_names: tuple[str, ...] | None = None
    """names of the policy's ``observation.state`` entries (its checkpoint's :data:`POLICY_INFO`; a
    policy trained on a state view takes fewer entries than the recorder writes); None: not
    recorded (checkpoints before it: the recorder's whole state)"""
    env_state_names: tuple[str, ...] | None = None
    """names of the policy's ``observation.environment_state`` entries (:data:`POLICY_INFO`); None:
    not recorded (eval then finds the layout by size)"""

    @property
    def cameras(self) -> tuple[str, ...]:
        """Camera names of the policy's image inputs."""
        return tuple(k.removeprefix(IMAGES + ".") for k in self.image_shapes)


def load_policy(checkpoint: Path, device: str = "cpu") -> LoadedPolicy:
    """Load a lerobot checkpoint folder (``.../pretrained_model``: config.json, model.safetensors,
    policy_pre/postprocessor.json) onto ``device``; ACT and Diffusion Policy only."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    path = Path(checkpoint)
    if not (path / "config.json").is_file() or not (path / "model.safetensors").is_file():
        raise FileNotFoundError(f"{path}: not a lerobot checkpoint (needs config.json and model.safetensors)")
    cfg = PreTrainedConfig.from_pretrained(str(path))
    if cfg.type not in SUPPORTED:
        raise ValueError(f"{path}: policy type {cfg.type!r} is not supported (supported: {SUPPORTED})")
    cfg.device = device
    policy = get_policy_class(cfg.type).from_pretrained(str(path), config=cfg)
    policy.eval()
    pre, post = make_pre_post_processors(policy.config, pretrained_path=str(path),
                                         preprocessor_overrides={"device_processor": {"device": device}})
    shapes = {k: tuple(int(x) for x in ft.shape) for k, ft in policy.config.image_features.items()}
    bad = [k for k, s in shapes.items() if len(s) != 3 or s[0] != 3]
    if bad:
        raise ValueError(f"{path}: image inputs {bad} are not RGB (3, H, W)")
    state = policy.config.robot_state_feature
    if state is None:
        raise ValueError(f"{path}: the policy has no {STATE} input")
    env_dim = int(env.shape[0]) if (env := policy.config.env_state_feature) else 0
    names, env_names = read_policy_info(path, int(state.shape[0]), env_dim)
    return LoadedPolicy(policy=policy, preprocessor=pre, postprocessor=post, type=cfg.type, device=device,
                        image_shapes=shapes, state_dim=int(state.shape[0]),
                        action_dim=int(policy.config.action_feature.shape[0]), env_state_dim=env_dim,
                        state_names=names, env_state_names=env_names)


def to_policy_batch(obs: list[dict[str, np.ndarray]], image_keys) -> dict[str, Any]:
    """Per-world observations -> a raw batch: state (B, S) float32, environment state (B, D) float32
    where the observations hold it, images (B, 3, H, W) float32 in [0, 1]."""
    import torch

    batch = {STATE: torch.from_numpy(np.stack([np.asarray(o[STATE], np.float32) for o in obs]))}
    if obs and ENV_STATE in obs[0]:
        batch[ENV_STATE] = torch.from_numpy(np.stack([np.asarray(o[ENV_STATE], np.float32) for o in obs]))
    for k in image_keys:
        hwc = np.stack([o[k] for o in obs])
        batch[k] = torch.from_numpy(hwc).permute(0, 3, 1, 2).float().div_(255.0)
    return batch


class _World:
    """One world's inference state during an episode."""

    def __init__(self, runner: BatchedRunner, seed: int) -> None:
        cfg = runner.loaded.policy.config
        self.actions: deque = deque()
        self.ensembler = None
        if runner.loaded.type == "act" and cfg.temporal_ensemble_coeff is not None:
            from lerobot.policies.act.modeling_act import ACTTemporalEnsembler

            self.ensembler = ACTTemporalEnsembler(cfg.temporal_ensemble_coeff, cfg.chunk_size)
        self.history: dict[str, deque] = {}
        if runner.loaded.type == "diffusion":
            import torch

            self.history = {STATE: deque(maxlen=cfg.n_obs_steps), IMAGES: deque(maxlen=cfg.n_obs_steps)}
            if runner.loaded.env_state_dim:
                self.history[ENV_STATE] = deque(maxlen=cfg.n_obs_steps)
            self.generator = torch.Generator().manual_seed(int(seed) % (2**63))
        self.steps = 0


class BatchedRunner:
    """Per-world chunking / ensembling around one :class:`LoadedPolicy` (see the module docstring).

    ``reset(world, seed)`` at an episode's start; ``act({world: observation})`` once per frame for
    the worlds acting at that frame -> {world: action (A,) float32}."""

    def __init__(self, loaded: LoadedPolicy) -> None:
        self.loaded = loaded
        self.worlds: dict[int, _World] = {}
        self.model_calls = 0  # batched network calls (chunks), for the report
        self.chunks = 0  # chunks predicted (one per world and call)

    def reset(self, world: int, seed: int = 0) -> None:
        self.worlds[world] = _World(self, seed)

    def act(self, obs: dict[int, dict[str, np.ndarray]]) -> dict[int, np.ndarray]:
        import torch

        lp = self.loaded
        ws = sorted(obs)
        missing = [w for w in ws if w not in self.worlds]
        if missing:
            raise RuntimeError(f"policy runner: worlds {missing} act before reset()")
        with torch.inference_mode():
            batch = lp.preprocessor(to_policy_batch([obs[w] for w in ws], lp.image_shapes))
            if lp.type == "act":
                out = self._act_act(ws, batch)
            else:
                out = self._act_diffusion(ws, batch)
            actions = lp.postprocessor(torch.stack([out[w] for w in ws]))
        res = {w: actions[j].detach().to("cpu").numpy().astype(np.float32) for j, w in enumerate(ws)}
        for w in ws:
            self.worlds[w].steps += 1
        return res

    # -- ACT ---------------------------------------------------------------------------------
    def _act_act(self, ws: list[int], batch: dict) -> dict:
        pol = self.loaded.policy
        n = pol.config.n_action_steps
        ens = [self.worlds[w].ensembler is not None for w in ws]
        need = [j for j, w in enumerate(ws) if ens[j] or not self.worlds[w].actions]
        out = {}
        if need:
            chunk = pol.predict_action_chunk(_rows(batch, need))
            self.model_calls += 1
            self.chunks += len(need)
            for r, j in enumerate(need):
                st = self.worlds[ws[j]]
                if st.ensembler is not None:
                    out[ws[j]] = st.ensembler.update(chunk[r:r + 1])[0]
                else:
                    st.actions.extend(chunk[r, :n])
        for w in ws:
            if w not in out:
                out[w] = self.worlds[w].actions.popleft()
        return out

    # -- Diffusion Policy ----------------------------------------------------------------------
    def _act_diffusion(self, ws: list[int], batch: dict) -> dict:
        import torch

        pol = self.loaded.policy
        cfg = pol.config
        keys = list(cfg.image_features)
        images = torch.stack([batch[k] for k in keys], dim=-4) if keys else None  # (B, ncam, 3, H, W)
        for j, w in enumerate(ws):
            h = self.worlds[w].history
            for key, value in ((STATE, batch[STATE][j]), (IMAGES, None if images is None else images[j]),
                               (ENV_STATE, batch[ENV_STATE][j] if ENV_STATE in h else None)):
                if value is None:
                    continue
                while len(h[key]) < h[key].maxlen - 1:  # lerobot's populate_queues: the first obs repeated
                    h[key].append(value)
                h[key].append(value)
        need = [w for w in ws if not self.worlds[w].actions]
        if need:
            hist = {STATE: torch.stack([torch.stack(list(self.worlds[w].history[STATE])) for w in need])}
            if ENV_STATE in self.worlds[need[0]].history:
                hist[ENV_STATE] = torch.stack([torch.stack(list(self.worlds[w].history[ENV_STATE])) for w in need])
            if images is not None:
                hist[IMAGES] = torch.stack([torch.stack(list(self.worlds[w].history[IMAGES])) for w in need])
            shape = (cfg.horizon, cfg.action_feature.shape[0])
            gens = [self.worlds[w].generator for w in need]
            noise = torch.stack([torch.randn(shape, generator=g) for g in gens])
            dev, dt = hist[STATE].device, hist[STATE].dtype
            # lerobot's generate_actions with one generator per world: the initial noise and the
            # DDPM steps' noise (diffusers' randn_tensor draws row i from generator i)
            cond = pol.diffusion._prepare_global_conditioning(hist)
            sample = pol.diffusion.conditional_sample(len(need), global_cond=cond, generator=gens,
                                                      noise=noise.to(device=dev, dtype=dt))
            start = cfg.n_obs_steps - 1
            acts = sample[:, start:start + cfg.n_action_steps]
            self.model_calls += 1
            self.chunks += len(need)
            for r, w in enumerate(need):
                self.worlds[w].actions.extend(acts[r])
        return {w: self.worlds[w].actions.popleft() for w in ws}


def _rows(batch: dict, rows: list[int]) -> dict:
    """The batch restricted to ``rows`` (tensors indexed on dim 0; other values kept)."""
    import torch

    idx = None
    out = {}
    for k, v in batch.items():
        if isinstance(v, torch.Tensor) and v.ndim >= 1:
            if idx is None or idx.device != v.device:
                idx = torch.as_tensor(rows, device=v.device)
            out[k] = v.index_select(0, idx)
        else:
            out[k] = v
    return out
