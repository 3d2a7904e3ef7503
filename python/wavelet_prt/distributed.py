"""Bakes spread over a Ray cluster: each shard of the bake is a Ray task that bakes one band of
tile rows (``prt bake --shard I/COUNT``), and the shards are merged into the file a single
process writes, byte for byte.

>>> import ray, wavelet_prt as wp
>>> ray.init(address="auto")                        # or ray.init() for this machine alone
>>> t = wp.distributed.bake("scene.toml", "out.prt", shards=16, cube=64)

Needs the ``ray`` extra (``pip install "./python[ray]"``). The scene's files must be readable
at the same path on every node (shared storage), as the shards are when ``via="storage"``.
"""

from __future__ import annotations

import inspect
import os
import tempfile
from typing import Any, Callable, Dict, List, Optional, Union

from . import Transport, _bake_file, _native, _progress
from . import bake as _bake


def _bake_to(scene: str, path: str, index: int, count: int, flags: Dict[str, Any]) -> None:
    """Bakes shard ``index`` of ``count`` to ``path`` with :func:`wavelet_prt.bake`'s flags."""
    bound = inspect.signature(_bake).bind(scene, path, shard=(index, count), progress=False,
                                          **flags)
    bound.apply_defaults()
    _bake_file(dict(bound.arguments))


def _shard_name(out: str, index: int, count: int) -> str:
    return os.path.join(out + ".shards", f"shard-{index}-of-{count}.prt")


def _bake_shard(scene: str, cwd: str, path: Optional[str], index: int, count: int,
                flags: Dict[str, Any], on_start: Optional[Callable[[int], None]]
                ) -> Union[str, bytes]:
    """One task: bakes shard ``index`` of ``count`` to ``path`` (shared storage; a file there
    that already holds this shard is kept) or to a temporary file whose bytes it returns.

    ``scene`` is the path as the caller gave it, relative to ``cwd``, the caller's folder: the
    file records it, so the task works from there (when the node has it), as a single bake
    from the caller's folder would."""
    if on_start is not None:
        on_start(index)
    before = os.getcwd()
    if not os.path.isabs(scene) and os.path.isdir(cwd):
        os.chdir(cwd)
    elif not os.path.isabs(scene):
        scene = os.path.join(cwd, scene)
    try:
        if path is not None:
            _bake_to(scene, path, index, count, flags)
            return path
        with tempfile.TemporaryDirectory(prefix="wavelet-prt-shard-") as folder:
            local = os.path.join(folder, f"shard-{index}-of-{count}.prt")
            _bake_to(scene, local, index, count, flags)
            with open(local, "rb") as f:
                return f.read()
    finally:
        os.chdir(before)


def bake(
    scene: Union[str, "os.PathLike[str]"],
    out: Union[str, "os.PathLike[str]"],
    shards: int = 4,
    *,
    cpus_per_shard: int = 1,
    via: str = "storage",
    max_retries: int = 3,
    keep_shards: bool = False,
    on_task_start: Optional[Callable[[int], None]] = None,
    progress: Any = None,
    **flags: Any,
) -> Transport:
    """Bakes ``scene`` into ``out`` as :func:`wavelet_prt.bake` does with the same ``flags``
    (``cube=64``, ``per_vertex=True``, ...), as ``shards`` Ray tasks of ``cpus_per_shard``
    CPUs each, and opens the merged file, which is byte-identical to a single bake's from
    this folder (a relative ``scene`` is read from this folder where a node has it).

    ``via="storage"``: each task writes its shard beside ``out`` (``OUT.shards/``, shared
    storage on a cluster); a shard file already there that holds this bake is kept, so a task
    retried after its shard was written, or the whole call run again after a failure, never
    bakes a finished shard twice. The folder is removed once merged unless ``keep_shards``.
    ``via="object_store"``: each task returns its shard's bytes through Ray's object store (no
    shared folder for the output; a retried task bakes its shard again).

    A task that fails or whose worker dies is retried up to ``max_retries`` times.
    ``on_task_start(index)`` runs in the worker before each attempt (logging, fault tests).
    Ray is started on this machine alone when it is not running yet.
    """
    import ray

    if shards < 1:
        raise ValueError(f"shards: {shards}; at least 1")
    if via not in ("storage", "object_store"):
        raise ValueError(f"via: `{via}`; expected storage or object_store")
    if "shard" in flags:
        raise ValueError("shard: the distributed bake chooses the shards itself")
    # Flags checked here, before any task: a misspelt keyword is a TypeError now, not on a node.
    inspect.signature(_bake).bind("scene", "out", **flags)
    scene, out = os.fspath(scene), os.path.abspath(os.fspath(out))
    if not ray.is_initialized():
        ray.init()
    task = ray.remote(_bake_shard).options(
        num_cpus=cpus_per_shard,
        max_retries=max_retries,
        retry_exceptions=True,
        # Each worker's kernels use the CPUs its task holds, not the whole machine.
        runtime_env={"env_vars": {"RAYON_NUM_THREADS": str(cpus_per_shard)}},
    )
    paths: List[Optional[str]] = [None] * shards
    if via == "storage":
        os.makedirs(out + ".shards", exist_ok=True)
        paths = [_shard_name(out, i, shards) for i in range(shards)]
    pending = {
        task.remote(scene, os.getcwd(), paths[i], i, shards, flags, on_task_start): i
        for i in range(shards)
    }
    report, bar = _progress(progress, f"baking {scene} in {shards} shards")
    done: List[str] = [""] * shards
    written: List[str] = []
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                i = pending.pop(ref)
                result = ray.get(ref)
                if isinstance(result, bytes):
                    local = _shard_name(out, i, shards)
                    os.makedirs(os.path.dirname(local), exist_ok=True)
                    with open(local, "wb") as f:
                        f.write(result)
                    written.append(local)
                    result = local
                done[i] = result
            if report is not None:
                report(shards - len(pending), shards)
    finally:
        if bar is not None:
            bar.close()
        for ref in pending:
            ray.cancel(ref, force=True)
    _native.merge(done, out)
    if not keep_shards:
        for path in set(done) | set(written):
            os.remove(path)
        try:
            os.rmdir(out + ".shards")
        except OSError:
            pass
    return Transport.open(out)
