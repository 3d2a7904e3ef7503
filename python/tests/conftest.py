"""What the tests share: the command line they compare with, and small scenes written into a
temporary folder."""

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]

# A sphere on a ground plane under a camera of 24 x 16 pixels, and a point light named "bulb".
SCENE = (Path(__file__).parent / "sphere_on_ground.toml").read_text()


@pytest.fixture(scope="session")
def prt() -> str:
    """The `prt` command line of this repository's release build (built once if missing)."""
    path = os.environ.get("PRT_BIN") or str(REPO / "target" / "release" / "prt")
    if not os.path.exists(path):
        subprocess.run(["cargo", "build", "--release", "--bin", "prt"], cwd=REPO, check=True)
    return path


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    """The test scene's file in a fresh folder."""
    path = tmp_path / "scene.toml"
    path.write_text(SCENE)
    return path


def run(*args: str) -> subprocess.CompletedProcess:
    """Runs a command, failing the test with its output when it fails."""
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    assert done.returncode == 0, f"{args}: {done.stderr}"
    return done


def sky(height: int = 32, width: int = 64) -> np.ndarray:
    """A lat-long sky that varies with direction in every channel, brightest near the zenith."""
    v = (np.arange(height, dtype=np.float32) + 0.5) / height
    u = (np.arange(width, dtype=np.float32) + 0.5) / width
    r = 0.2 + 2.0 * (1.0 - v)[:, None] * (1.0 + 0.5 * np.cos(2 * np.pi * u))[None, :]
    g = 0.3 + 1.5 * (1.0 - v)[:, None] ** 2 * np.ones_like(u)[None, :]
    b = 0.4 + 0.8 * np.sin(np.pi * v)[:, None] * (1.0 + np.sin(4 * np.pi * u))[None, :]
    return np.ascontiguousarray(np.stack([r, g, b], axis=-1).astype(np.float32))
