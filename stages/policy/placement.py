"""Which GPU and batch size each training run of the device driver gets (issue 17).

``place`` maps a policy to the GPUs its runs share (``{"act": [0, 1, 2], "diffusion": [3]}``: one
family's ACT per GPU, the three Diffusion Policy runs together on the fourth); runs of a policy not
named there go round robin over every GPU, in their order. ``per_policy`` reads the command line's
``N`` (every policy) and ``POLICY=N`` values.
"""

from __future__ import annotations


def per_policy(values: list[str] | None, what: str) -> dict[str, int]:
    """``["64", "diffusion=32"]`` -> ``{"*": 64, "diffusion": 32}`` (``*``: every other policy);
    raises ``ValueError`` (one line) on a value that is not ``N`` or ``POLICY=N`` with N >= 1."""
    out: dict[str, int] = {}
    for v in values or []:
        key, _, num = v.rpartition("=")
        try:
            n = int(num)
        except ValueError:
            n = 0
        if n < 1 or (key and not key.isidentifier()):
            raise ValueError(f"{what}: expected N or POLICY=N with N >= 1, got {v!r}")
        out[key or "*"] = n
    return out


def parse_place(values: list[str] | None, n_gpus: int) -> dict[str, list[int]]:
    """``["act=0,1,2", "diffusion=3"]`` -> ``{"act": [0, 1, 2], "diffusion": [3]}``; raises
    ``ValueError`` (one line) on a malformed value or a GPU index the machine does not have."""
    out: dict[str, list[int]] = {}
    for v in values or []:
        pol, _, ids = v.partition("=")
        try:
            gpus = [int(x) for x in ids.split(",")]
        except ValueError:
            gpus = []
        if not pol or not gpus or any(g < 0 or g >= n_gpus for g in gpus):
            raise ValueError(f"--place: expected POLICY=GPU[,GPU...] with GPUs 0-{n_gpus - 1}, got {v!r}")
        out[pol] = gpus
    return out


def run_devices(policies: list[str], gpus: list[str], place: dict[str, list[int]] | None = None) -> list[str]:
    """The device of each run (``policies[k]`` is run k's policy): round robin over the policy's
    GPUs in ``place``, else over ``gpus`` by the run's position (``gpus``: "cuda:N" or "cpu")."""
    place = place or {}
    seen: dict[str, int] = {}
    out = []
    for k, pol in enumerate(policies):
        if pol in place and gpus != ["cpu"]:
            i = seen.get(pol, 0)
            seen[pol] = i + 1
            out.append(gpus[place[pol][i % len(place[pol])]])
        else:
            out.append(gpus[k % len(gpus)])
    return out
