"""Reads a transport file's Haar matrix into numpy, every stored value decoded with its row and
coefficient, as the format documents it in `src/store/transport/mod.rs`: strips in light-major
bands (versions 7 to 9) or columns (versions 3 to 6). Shared by the scripts beside it; needs numpy and
safetensors.
"""

import json
import struct

import numpy as np
from safetensors.numpy import load_file

BLOCK_ROWS = 256
STRIP_ROWS = 8
BAND_BLOCKS = 16
TILE = 16


def read(path):
    """(meta, tensors, rows, coefficients, values): the file's `meta` JSON, its tensors, and each
    stored value's row (int64), Haar coefficient (int64) and decoded value (float64)."""
    with open(path, "rb") as f:
        (n,) = struct.unpack("<Q", f.read(8))
        meta = json.loads(json.loads(f.read(n))["__metadata__"]["meta"])
    t = load_file(path)
    c = 6 * meta["cube_n"] ** 2
    starts = t["tile_row_start"].astype(np.int64)
    # Each tile's rows in blocks of 256: the first row of every block, and each tile's blocks.
    per_tile = [np.arange(a, b, BLOCK_ROWS) for a, b in zip(starts[:-1], starts[1:])]
    block_row0 = np.concatenate(per_tile + [np.zeros(0, np.int64)]).astype(np.int64)
    scale = np.power(2.0, (t["col_scale"].astype(np.float64).ravel() - 192.0) / 4.0)
    if meta["format_version"] < 7:
        counts = t["col_count"].astype(np.int64).ravel()
        blocks = len(block_row0)
        slot_block = np.repeat(np.arange(blocks), c)
        slot_coeff = np.tile(np.arange(c), blocks)
        slot = np.repeat(np.arange(len(counts)), counts)
        rows = block_row0[slot_block[slot]] + t["entry_row"].astype(np.int64)
        raw = t["entry_value"].astype(np.float64)
    else:
        tile_block_start = np.concatenate([[0], np.cumsum([len(p) for p in per_tile])])
        tx = -(-meta["width"] // TILE)
        ty = (len(starts) - 1) // tx
        # Groups of whole tile rows, each closed once it holds 16 blocks (the last whatever is
        # left), cut into bands of at most 16 blocks.
        bands, first = [], 0
        for y in range(1, ty + 1):
            b0, b1 = tile_block_start[first * tx], tile_block_start[y * tx]
            if b1 - b0 >= BAND_BLOCKS or y == ty:
                bands += [(b, min(b + BAND_BLOCKS, b1)) for b in range(b0, b1, BAND_BLOCKS)]
                first = y
        # Slots run band by band, coefficient by coefficient, block by block.
        slot_block = np.concatenate([np.tile(np.arange(a, b), c) for a, b in bands] + [[]])
        slot_coeff = np.concatenate([np.repeat(np.arange(c), b - a) for a, b in bands] + [[]])
        slot_block, slot_coeff = slot_block.astype(np.int64), slot_coeff.astype(np.int64)
        counts = t["strip_count"].astype(np.int64).ravel()
        strip_slot = np.repeat(np.arange(len(counts)), counts)
        lanes = t["strip_value"]
        keep = lanes != 0
        strip_rows = (
            block_row0[slot_block[strip_slot]][:, None]
            + STRIP_ROWS * t["strip_place"].astype(np.int64)[:, None]
            + np.arange(STRIP_ROWS)
        )
        slot = np.broadcast_to(strip_slot[:, None], keep.shape)[keep]
        rows = strip_rows[keep]
        raw = lanes[keep].astype(np.float64)
    values = raw * scale[slot] * t["row_scale"][rows]
    return meta, t, rows, slot_coeff[slot], values
