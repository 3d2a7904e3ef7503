#!/usr/bin/env python3
"""Traces the bake's shadow rays with Embree's one-ray occlusion query and compares its rate with
the engine's tracer on the same rays and triangles.

The rays come from `cargo run --release --example shadow_rays -- SCENE.toml DIR`, which also
times the engine's tracer on one thread, one ray at a time and in the bake's packets, and the
bake's whole pipeline per ray; all three rates are set beside Embree's. This script needs numpy and the `embreex`
package (Embree 4 bindings; `pip install embreex`); it is not a build dependency. embreex's
`EmbreeScene.run(..., query='OCCLUDED')` calls `rtcOccluded1` once per ray from compiled code, so
the Python interpreter is outside the timed loop. The rate is rays per CPU-second of this
process (`time.process_time`), the median of three passes, the scene's build excluded.

Usage: python3 scripts/embree_shadow_rays.py DIR
"""

import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

PASSES = 3


def main() -> int:
    if len(sys.argv) != 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    folder = Path(sys.argv[1])
    try:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh
    except ImportError as e:
        print(f"embreex is not installed ({e}): pip install embreex", file=sys.stderr)
        return 2
    meta = json.loads((folder / "rays.json").read_text())
    triangles = np.fromfile(folder / "triangles.f32", dtype="<f4")
    rays = np.fromfile(folder / "rays.f32", dtype="<f4")
    ours = np.fromfile(folder / "occluded.u8", dtype=np.uint8)
    count = meta["rays"]
    if triangles.size != meta["triangles"] * 9 or rays.size != count * 7 or ours.size != count:
        print(f"{folder}: the files do not hold the counts rays.json names", file=sys.stderr)
        return 1
    triangles = triangles.reshape(-1, 3, 3)
    rays = rays.reshape(-1, 7)
    origins = np.ascontiguousarray(rays[:, 0:3])
    dirs = np.ascontiguousarray(rays[:, 3:6])
    # Embree takes no infinite t_far through embreex's dists; the scene's extent bounds any hit.
    extent = float(np.abs(triangles).max()) * 4.0 + 1.0
    dists = np.where(np.isinf(rays[:, 6]), extent, rays[:, 6]).astype(np.float32)

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, triangles)
    scene.run(origins[:1], dirs[:1], dists=dists[:1], query="OCCLUDED")  # builds the scene

    seconds = []
    answer = None
    for _ in range(PASSES):
        start = time.process_time()
        answer = scene.run(origins, dirs, dists=dists.copy(), query="OCCLUDED")
        seconds.append(time.process_time() - start)
    median = statistics.median(seconds)
    theirs = (np.asarray(answer) != -1).astype(np.uint8)
    rate = count / median
    ours_rate = meta["rays_per_cpu_second"]
    disagree = int(np.count_nonzero(theirs != ours))
    print(
        f"{meta['scene']}: {meta['triangles']} triangles, {count} shadow rays "
        f"({100.0 * theirs.mean():.1f}% occluded by Embree, {100.0 * ours.mean():.1f}% by the engine; "
        f"{disagree} rays ({100.0 * disagree / count:.3f}%) answered differently)"
    )
    print(
        f"Embree rtcOccluded1: {rate / 1e6:.2f} M rays per CPU-second (median of {PASSES}); "
        f"the engine's tracer: {ours_rate / 1e6:.2f} M, {ours_rate / rate:.2f}x Embree's rate"
    )
    packet_rate = meta.get("packet_rays_per_cpu_second")
    if packet_rate is not None:
        print(
            f"the engine's tracer in packets of 8 x 8 texels (as the bake traces them): "
            f"{packet_rate / 1e6:.2f} M rays per CPU-second, {packet_rate / rate:.2f}x Embree's "
            f"one-ray rate"
        )
    bake_rate = meta.get("bake_rays_per_cpu_second")
    if bake_rate is not None:
        print(
            f"the engine's whole bake: {bake_rate / 1e6:.2f} M rays per CPU-second, "
            f"{bake_rate / rate:.2f}x Embree's one-ray rate"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
