"""Errors raise ValueError or OSError with the command line's messages; Ctrl-C and a failing
progress function cancel a bake and leave nothing behind."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import wavelet_prt as wp
from conftest import SCENE, run


def cli_error(*args) -> str:
    """The message of the command line's error, without its `error: ` prefix."""
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    assert done.returncode != 0
    line = [l for l in done.stderr.splitlines() if l.startswith("error: ")][0]
    return line[len("error: "):]


def test_a_missing_file_is_a_file_not_found_error_with_the_command_lines_message(prt, tmp_path):
    missing = tmp_path / "missing.prt"
    with pytest.raises(FileNotFoundError) as e:
        wp.Transport.open(missing)
    assert str(e.value) == cli_error(prt, "info", missing)


def test_a_bad_flag_value_is_a_value_error_with_the_command_lines_message(prt, tmp_path, scene):
    with pytest.raises(ValueError) as e:
        wp.bake(scene, tmp_path / "x.prt", cube=12)
    assert str(e.value) == cli_error(prt, "bake", scene, "-o", tmp_path / "x.prt", "--cube", "12")
    assert not (tmp_path / "x.prt").exists()


def test_a_bad_relight_is_a_value_error_with_the_command_lines_message(prt, tmp_path, scene):
    t = wp.bake(scene, tmp_path / "t.prt", cube=4, sh_order=2)
    for kwargs, args in [
        ({"terms": 0}, ["--terms", "0"]),
        ({"terms": 97}, ["--terms", "97"]),
        ({"method": "sh", "sh_order": 5}, ["--method", "sh", "--sh-order", "5"]),
        ({"method": "haar"}, ["--method", "haar"]),
        ({"lights": {"lamp": 1}}, ["--light", "lamp=1"]),
        ({"yaw": float("nan")}, ["--yaw", "NaN"]),
        ({"eye": [0, 1, 2]}, ["--eye", "0,1,2"]),
    ]:
        with pytest.raises(ValueError) as e:
            t.relight("sun:30,40", **kwargs)
        message = cli_error(prt, "relight", t.path, "--env", "sun:30,40", "-o",
                            tmp_path / "x.exr", "--device", "cpu", *args)
        assert message.endswith(str(e.value)) or str(e.value).endswith(message), (kwargs, message)


def test_a_misspelt_keyword_or_a_per_vertex_flag_alone_is_refused(tmp_path, scene):
    with pytest.raises(TypeError):
        wp.bake(scene, tmp_path / "x.prt", cubes=8)
    with pytest.raises(ValueError, match="per_vertex"):
        wp.bake(scene, tmp_path / "x.prt", refine_shadows=True)
    with pytest.raises(ValueError, match="lossless"):
        wp.bake(scene, tmp_path / "x.prt", lossless=True, threshold=0.01)


def test_an_environment_array_must_be_rgb_finite_and_lit(tmp_path, scene):
    t = wp.bake(scene, tmp_path / "t.prt", cube=4)
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        t.relight(np.ones((8, 16, 4), dtype=np.float32))
    bad = np.ones((8, 16, 3), dtype=np.float32)
    bad[2, 3, 1] = np.nan
    with pytest.raises(ValueError):
        t.relight(bad)
    with pytest.raises(ValueError, match="lights nothing"):
        t.relight(np.zeros((8, 16, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="negative"):
        t.relight(-np.ones((8, 16, 3), dtype=np.float32))


def test_progress_reaches_the_end_and_an_exception_from_it_cancels_the_bake(tmp_path, scene):
    seen = []
    wp.bake(scene, tmp_path / "a.prt", cube=8, progress=lambda d, n: seen.append((d, n)))
    assert seen and seen[-1][0] == seen[-1][1] > 0
    assert all(a[0] <= b[0] for a, b in zip(seen, seen[1:]))

    big = tmp_path / "big.toml"
    big.write_text(SCENE.replace("width = 24", "width = 240").replace("height = 16", "height = 160"))

    def stop(done, total):
        if done > 0:
            raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        wp.bake(big, tmp_path / "b.prt", cube=32, progress=stop)
    assert not (tmp_path / "b.prt").exists()
    assert [p for p in os.listdir(tmp_path) if p.startswith("b.prt")] == []


def test_ctrl_c_cancels_a_bake_and_leaves_nothing(tmp_path):
    # Ctrl-C as a terminal sends it: SIGINT from outside the process, a second after the bake
    # began (the bake takes half a minute). The child handles SIGINT as an interactive Python
    # does even where it was started with SIGINT ignored (a background job of a script), which
    # Python would otherwise keep.
    big = tmp_path / "big.toml"
    big.write_text(SCENE.replace("width = 24", "width = 320").replace("height = 16", "height = 240"))
    script = textwrap.dedent(
        f"""
        import signal, time
        import wavelet_prt as wp
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("baking", flush=True)
        start = time.time()
        try:
            wp.bake({str(big)!r}, {str(tmp_path / "c.prt")!r}, cube=64, progress=False)
            print("finished")
        except KeyboardInterrupt:
            print("cancelled after", round(time.time() - start, 1))
        """
    )
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline() == "baking\n"
        time.sleep(1.0)
        child.send_signal(signal.SIGINT)
        out, err = child.communicate(timeout=120)
    finally:
        child.kill()
    assert child.returncode == 0, err
    assert out.startswith("cancelled"), out
    assert float(out.split()[-1]) < 10
    assert [p for p in os.listdir(tmp_path) if p.startswith("c.prt")] == []
