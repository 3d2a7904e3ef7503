"""A bake in 4 shards on a local Ray cluster of 2 CPUs against the same bake in one process, in
turn in one run: their wall times, their ratio, and whether the files are identical.

    python python/benchmarks/ray_bake.py [assets/scenes/demo.toml] [--runs 3]

The cluster is started once before the runs, as a running cluster would be; the times count
the tasks, the shards' transfer and the merge.
"""

import argparse
import os
import tempfile
import time

import numpy as np
import ray

import wavelet_prt as wp

parser = argparse.ArgumentParser()
parser.add_argument("scene", nargs="?", default="assets/scenes/demo.toml")
parser.add_argument("--runs", type=int, default=3)
parser.add_argument("--shards", type=int, default=4)
args = parser.parse_args()

start = time.perf_counter()
ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
print(f"ray.init: {time.perf_counter() - start:.1f} s (not counted)")
single_s, ray_s, same = [], [], []
with tempfile.TemporaryDirectory() as folder:
    one, spread = os.path.join(folder, "one.prt"), os.path.join(folder, "ray.prt")
    for run in range(args.runs):
        for f in (one, spread):
            if os.path.exists(f):
                os.remove(f)
        start = time.perf_counter()
        wp.bake(args.scene, one, progress=False)
        single_s.append(time.perf_counter() - start)
        start = time.perf_counter()
        wp.distributed.bake(args.scene, spread, shards=args.shards)
        ray_s.append(time.perf_counter() - start)
        same.append(open(one, "rb").read() == open(spread, "rb").read())
        print(f"run {run + 1}: one process {single_s[-1]:.2f} s, {args.shards} shards on Ray "
              f"{ray_s[-1]:.2f} s, identical: {same[-1]}")
a, b = np.median(single_s), np.median(ray_s)
print(f"{args.scene} (the bake's defaults): one process {a:.2f} s, {args.shards} shards on a "
      f"2-CPU local Ray cluster {b:.2f} s (medians of {args.runs}): {b / a:.2f}x; "
      f"byte-identical in every run: {all(same)}")
