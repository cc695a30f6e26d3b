"""Shared helpers of the engine tests: where the sample runs are, reading them plainly."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]


def shared_data_dir() -> Path | None:
    """The shared sample-run folder (env SHARED_DIR, else ../shared next to the repo)."""
    env = os.environ.get("SHARED_DIR")
    for cand in ([Path(env)] if env else []) + [REPO.parent / "shared"]:
        if (cand / "data").is_dir():
            return cand / "data"
    return None


def sample(name: str) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Columns of a sample CSV and its truth arrays; skips the test when shared/ is absent."""
    d = shared_data_dir()
    if d is None or not (d / f"{name}.csv").exists():
        pytest.skip(f"shared sample {name} not available (set SHARED_DIR)")
    raw = np.loadtxt(d / f"{name}.csv", delimiter=",", skiprows=1)
    truth = dict(np.load(d / f"{name}.truth.npz"))
    return raw, truth
