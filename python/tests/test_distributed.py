"""Bakes spread over a local Ray cluster of 2 CPUs: the merged file is the single bake's byte for
byte, a task whose worker dies is retried, and a finished shard is never baked twice."""

import os
from pathlib import Path

import pytest

import ray  # noqa: E402

import wavelet_prt as wp  # noqa: E402
from conftest import SCENE  # noqa: E402

FLAGS = {"cube": 16, "sh_order": 3}


@pytest.fixture(scope="module")
def cluster():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def wide(tmp_path_factory) -> Path:
    """The test scene at 96 x 64 pixels: 6 bands of 16-pixel tile rows to share out."""
    path = tmp_path_factory.mktemp("wide") / "scene.toml"
    path.write_text(SCENE.replace("width = 24", "width = 96").replace("height = 16", "height = 64"))
    return path


@pytest.fixture(scope="module")
def single(wide) -> bytes:
    out = wide.parent / "single.prt"
    wp.bake(wide, out, **FLAGS)
    return out.read_bytes()


@pytest.mark.parametrize("via", ["storage", "object_store"])
def test_four_shards_on_two_cpus_are_the_single_bake_byte_for_byte(cluster, wide, single, via,
                                                                    tmp_path):
    out = tmp_path / "ray.prt"
    t = wp.distributed.bake(wide, out, shards=4, via=via, **FLAGS)
    assert out.read_bytes() == single
    assert t.cube == 16
    assert not (tmp_path / "ray.prt.shards").exists()


def _die_once(marks: str):
    """A task start that kills the worker of shard 1 on its first attempt, and logs attempts."""

    def start(index: int) -> None:
        log = os.path.join(marks, f"attempt-{index}-{os.getpid()}-{len(os.listdir(marks))}")
        open(log, "w").close()
        if index == 1 and not os.path.exists(os.path.join(marks, "died")):
            open(os.path.join(marks, "died"), "w").close()
            os._exit(1)

    return start


def test_a_task_whose_worker_dies_is_retried(cluster, wide, single, tmp_path):
    marks = tmp_path / "marks"
    marks.mkdir()
    out = tmp_path / "ray.prt"
    wp.distributed.bake(wide, out, shards=4, on_task_start=_die_once(str(marks)), **FLAGS)
    assert out.read_bytes() == single
    attempts = [m.split("-")[1] for m in os.listdir(marks) if m.startswith("attempt")]
    assert sorted(attempts) == ["0", "1", "1", "2", "3"]


def test_a_finished_shard_is_never_baked_twice(cluster, wide, single, tmp_path):
    out = tmp_path / "ray.prt"
    wp.distributed.bake(wide, out, shards=4, keep_shards=True, **FLAGS)
    shards = sorted((tmp_path / "ray.prt.shards").iterdir())
    assert len(shards) == 4
    stamps = {p.name: p.stat().st_mtime_ns for p in shards}
    # One shard lost, as after a failure: the call run again bakes it alone.
    lost = shards[2]
    lost.unlink()
    out.unlink()
    wp.distributed.bake(wide, out, shards=4, keep_shards=True, **FLAGS)
    assert out.read_bytes() == single
    for p in sorted((tmp_path / "ray.prt.shards").iterdir()):
        if p.name == lost.name:
            assert p.exists()
        else:
            assert p.stat().st_mtime_ns == stamps[p.name], f"{p.name} was baked again"


def test_a_scene_named_relative_to_this_folder_gives_the_single_bakes_file(cluster, wide,
                                                                          monkeypatch):
    # The file records the scene's path as given: the tasks read it from the caller's folder.
    monkeypatch.chdir(wide.parent)
    wp.bake("scene.toml", "relative-single.prt", **FLAGS)
    wp.distributed.bake("scene.toml", "relative-ray.prt", shards=3, **FLAGS)
    single = (wide.parent / "relative-single.prt").read_bytes()
    assert (wide.parent / "relative-ray.prt").read_bytes() == single
