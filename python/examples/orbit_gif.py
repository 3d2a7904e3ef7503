"""A per-vertex bake relit from a camera orbiting the scene, written as a GIF.

    cargo run --release -- demo            # writes prt-demo/demo_vertices.prt
    python python/examples/orbit_gif.py prt-demo/demo_vertices.prt blender_sunrise
"""

import sys

import numpy as np
from PIL import Image

import wavelet_prt as wp

path = sys.argv[1] if len(sys.argv) > 1 else "prt-demo/demo_vertices.prt"
env = sys.argv[2] if len(sys.argv) > 2 else "blender_sunrise"
t = wp.Transport.open(path)
camera = t.meta["camera"]
eye, target = np.array(camera["eye"]), np.array(camera["target"])
radius = np.hypot(*(eye - target)[[0, 2]])
frames = []
for angle in np.linspace(0, 2 * np.pi, 36, endpoint=False):
    at = target + [radius * np.sin(angle), eye[1] - target[1], radius * np.cos(angle)]
    img = t.relight(env, terms=200, eye=at, target=target, width=320, height=240)
    srgb = np.clip(img / np.percentile(img, 99.5), 0, 1) ** (1 / 2.2)
    frames.append(Image.fromarray((255 * srgb).astype(np.uint8)))
frames[0].save("orbit.gif", save_all=True, append_images=frames[1:], duration=80, loop=0)
print(f"wrote orbit.gif ({len(frames)} frames)")
