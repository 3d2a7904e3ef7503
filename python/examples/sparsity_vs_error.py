"""Error against kept terms: wavelets (the K largest Haar terms) against spherical harmonics, on
a baked transport under one environment, as the README's plot shows it.

    cargo run --release -- demo            # writes prt-demo/demo.prt
    python python/examples/sparsity_vs_error.py prt-demo/demo.prt blender_sunrise
"""

import os
import sys

import matplotlib.pyplot as plt
import numpy as np

import wavelet_prt as wp

path = sys.argv[1] if len(sys.argv) > 1 else "prt-demo/demo.prt"
env = sys.argv[2] if len(sys.argv) > 2 else "blender_sunrise"
t = wp.Transport.open(path)
mask = t.coverage()
truth = t.relight(env, method="full", background="black")
error = lambda img: 100 * wp.compare(img, truth, mask)["rel_l2"]  # noqa: E731

ks = np.unique(np.geomspace(1, 6 * t.cube**2, 40).astype(int))
wavelet = [error(t.relight(env, terms=int(k), background="black")) for k in ks]
orders = range(1, t.sh_order + 1)
sh = [error(t.relight(env, method="sh", sh_order=n, background="black")) for n in orders]

kept = np.array(wavelet) > 0  # every term kept is exact: no point on a log axis
plt.loglog(ks[kept], np.array(wavelet)[kept], "o-", label="wavelet (K largest Haar terms)")
plt.loglog([n * n for n in orders], sh, "s-", label="spherical harmonics (n² terms)")
plt.xlabel("terms kept")
plt.ylabel("relative L2 error against every term (%)")
plt.title(f"{os.path.basename(path)} under {env}")
plt.grid(True, which="both", alpha=0.3)
plt.legend()
plt.savefig("sparsity_vs_error.png", dpi=120)
print("wrote sparsity_vs_error.png")
