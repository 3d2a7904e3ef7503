"""What a call from Python adds to a relight, and how fast a sweep of K runs, on a baked
transport (by default the demo's, from `cargo run --release -- demo`).

    python python/benchmarks/overhead.py [prt-demo/demo.prt] [blender_sunrise]

Prints the medians of warm relights at K = 200 called from Python and timed inside the engine,
taken in turn in one run, their ratio, and the time of 100 relights at K from 1 to 6 N²
(log-spaced).
"""

import sys
import time

import numpy as np

import wavelet_prt as wp

path = sys.argv[1] if len(sys.argv) > 1 else "prt-demo/demo.prt"
env_name = sys.argv[2] if len(sys.argv) > 2 else "blender_sunrise"
t = wp.Transport.open(path)
env = wp.Environment.from_spec(env_name)
for _ in range(5):  # warm: the light prepared, the pages of the image and the kernels touched
    t.relight(env, terms=200, background="black")
    t.time_relight(env, terms=200, repeats=1)

python_s, engine_s = [], []
for _ in range(60):
    start = time.perf_counter()
    t.relight(env, terms=200, background="black")
    python_s.append(time.perf_counter() - start)
    engine_s.append(t.time_relight(env, terms=200, repeats=1)[0])
py_ms, rust_ms = 1e3 * np.median(python_s), 1e3 * np.median(engine_s)
print(f"K = 200 on {path} under {env_name}: from Python {py_ms:.3f} ms, in the engine "
      f"{rust_ms:.3f} ms (medians of 60, in turn): Python adds {100 * (py_ms / rust_ms - 1):.1f}%")

ks = np.geomspace(1, 6 * t.cube**2, 100).round().astype(int)
sweeps = []
for _ in range(3):
    start = time.perf_counter()
    for k in ks:
        t.relight(env, terms=int(k), background="black")
    sweeps.append(time.perf_counter() - start)
print(f"100 relights, K from 1 to {6 * t.cube**2} log-spaced: {np.median(sweeps):.2f} s "
      f"(median of 3: {', '.join(f'{s:.2f}' for s in sweeps)})")
