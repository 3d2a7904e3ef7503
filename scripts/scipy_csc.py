#!/usr/bin/env python3
"""Times scipy's sparse product on a transport file's Haar matrix, as the peer of the engine's
wavelet kernel: the rate, in stored coefficients per CPU-second, of the full product and of
K-term products.

The matrix is read from the file (safetensors; the tensors the format documents in
`src/store/transport/mod.rs`), every value decoded (integer x column scale x row scale) into a
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

import json
import statistics
import struct
import sys
import time

import numpy as np
import scipy.sparse
from safetensors.numpy import load_file

PASSES = 7
BLOCK_ROWS = 256


def matrix(path):
    with open(path, "rb") as f:
        (n,) = struct.unpack("<Q", f.read(8))
        meta = json.loads(json.loads(f.read(n))["__metadata__"]["meta"])
    t = load_file(path)
    version = meta["format_version"]
    if "entry_row" not in t:
        sys.exit(f"{path}: format {version} stores no column entries this script reads")
    n_side = meta["cube_n"]
    c = 6 * n_side * n_side
    tile_rows = t["tile_row_start"].astype(np.int64)
    block_start = []
    for a, b in zip(tile_rows[:-1], tile_rows[1:]):
        block_start.extend(range(a, b, BLOCK_ROWS))
    block_start = np.array(block_start, dtype=np.int64)
    counts = t["col_count"].astype(np.int64)
    blocks = counts.shape[0]
    assert blocks == len(block_start), "block tables do not match the tiles"
    per_slot = counts.ravel()
    cols = np.repeat(np.tile(np.arange(c), blocks), per_slot)
    block_of = np.repeat(np.repeat(np.arange(blocks), c), per_slot)
    rows = block_start[block_of] + t["entry_row"].astype(np.int64)
    codes = np.repeat(t["col_scale"].ravel(), per_slot).astype(np.float64)
    scale = np.power(2.0, (codes - 192.0) / 4.0)
    values = t["entry_value"].astype(np.float64) * scale * t["row_scale"][rows]
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
