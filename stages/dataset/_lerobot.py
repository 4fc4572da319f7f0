"""lerobot, imported the way every dataset module needs it: offline, quiet."""

from __future__ import annotations

import os
from typing import Any


def import_lerobot() -> Any:
    """Import lerobot's dataset package offline (no hub access) and quiet libav's encoder chatter."""
    os.environ.setdefault("HF_HUB_OFFLINE", "1")
    import av
    import datasets
    import lerobot.datasets as lds

    datasets.disable_progress_bars()
    av.logging.set_libav_level(av.logging.ERROR)  # lerobot re-installs ffmpeg's terminal logger
    return lds
