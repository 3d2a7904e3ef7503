#!/usr/bin/env python3
"""Times scipy's sparse product on a transport file's Haar matrix, as the peer of the engine's
wavelet kernel: the rate, in stored coefficients per CPU-second, of the full product and of
K-term products.

The matrix is read from the file (`prt_matrix.py` beside this script: the tensors the format
documents in `src/store/transport/mod.rs`), every value decoded (integer x column scale x row scale) into a
scipy CSC matrix of f32 values and int32 row indices. The full product is `A @ L` with an RGB
light of every coefficient; a K-term product is `A[:, kept] @ L[kept]`, the column selection
included (it is how a scipy user takes K terms), the kept columns the K of largest mean
magnitude (`transport_magnitude`, the transport weighting's order). scipy's products run on one
thread, so CPU-seconds are seconds of one thread. Medians of seven passes. Compare with the
engine's nonzeros touched per kernel second per thread (`prt relight FILE --terms K` prints
both, on two threads here).

Needs numpy, scipy and safetensors (`pip install numpy scipy safetensors`); not a build
dependency.

Usage: python3 scripts/scipy_csc.py FILE.prt [K ...]
"""

import statistics
import sys
import time

import numpy as np
import scipy.sparse

import prt_matrix

PASSES = 7


def matrix(path):
    meta, t, rows, cols, values = prt_matrix.read(path)
    c = 6 * meta["cube_n"] ** 2
    shape = (len(t["row_scale"]), c)
    a = scipy.sparse.csc_matrix(
        (values.astype(np.float32), (rows.astype(np.int32), cols.astype(np.int32))), shape=shape
    )
    a.sort_indices()
    return a, t["transport_magnitude"]


def timed(f):
    times = []
    for _ in range(PASSES):
        start = time.process_time()
        f()
        times.append(time.process_time() - start)
    return statistics.median(times)


def main() -> int:
    if len(sys.argv) < 2:
        print(__doc__.strip().splitlines()[-1], file=sys.stderr)
        return 2
    a, magnitude = matrix(sys.argv[1])
    ks = [int(k) for k in sys.argv[2:]] or [100, 200, 1000]
    rng = np.random.default_rng(1)
    light = rng.random((a.shape[1], 3), dtype=np.float32)
    print(f"{a.shape[0]} rows x {a.shape[1]} coefficients, {a.nnz} stored")
    seconds = timed(lambda: a @ light)
    print(f"full: {seconds * 1e3:.1f} ms, {a.nnz / seconds / 1e6:.0f} M coefficients per CPU-second")
    order = np.argsort(-magnitude, kind="stable")
    for k in ks:
        kept = np.sort(order[:k])
        lk = light[kept]
        nnz = int(np.diff(a.indptr)[kept].sum())
        seconds = timed(lambda: a[:, kept] @ lk)
        sub = a[:, kept]
        product = timed(lambda: sub @ lk)
        print(
            f"K = {k}: {nnz} coefficients, {seconds * 1e3:.2f} ms with the selection "
            f"({nnz / seconds / 1e6:.0f} M per CPU-second), {product * 1e3:.2f} ms the product "
            f"alone ({nnz / product / 1e6:.0f} M per CPU-second)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
