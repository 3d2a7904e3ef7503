"""All-frequency precomputed radiance transfer, from Python.

A scene is baked once into light transport against the texels of a cube map; any environment
map then relights it. Relighting keeps the light's K largest Haar terms (Ng, Ramamoorthi &
Hanrahan 2003) or its spherical harmonics, so a script can sweep the kept terms, the SH order or
a light, and measure the error, with images as numpy arrays.

>>> import wavelet_prt as wp
>>> t = wp.bake("scene.toml", "out.prt", cube=32)           # keywords: `prt bake`'s flags
>>> img = t.relight(env="blender_sunrise", terms=200)        # float32, shape (H, W, 3)
>>> img = t.relight(env=array, method="full")                # an (H, W, 3) lat-long array

Keyword names and defaults are those of the command line's flags (``--sh-order`` is
``sh_order``). Errors raise ``ValueError`` (or ``OSError`` for files the system cannot read or
write) with the command line's messages. The work runs without the GIL; Ctrl-C cancels a bake.
"""

from __future__ import annotations

import copy
import inspect
import json
import os
import sys
from collections import OrderedDict
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _native

__all__ = [
    "Environment",
    "Transport",
    "bake",
    "bake_defaults",
    "compare",
    "merge",
    "read_image",
    "save_image",
    "DEFAULT_TERMS",
]

__version__: str = _native.VERSION

#: Kept wavelet terms K when none are asked for (``prt relight --terms``).
DEFAULT_TERMS: int = _native.DEFAULT_TERMS

Environment = _native.Environment

#: What ``env=`` takes: a file, a bundled map's name, ``"sun:ELEV,AZIM[,RADIUS]"``, an
#: (H, W, 3) lat-long array, an :class:`Environment`, or ``None`` (the local lights alone).
EnvLike = Union[str, "os.PathLike[str]", np.ndarray, "Environment", None]

#: Progress: ``None`` shows a bar when on a terminal or in a notebook, ``True`` always,
#: ``False`` never; a function is called as ``progress(done, total)``.
ProgressLike = Union[None, bool, Callable[[int, int], Any]]

# Environments made from a spec, kept so that relighting with the same name or file again
# prepares nothing again (a file is made again when it changes).
_ENVIRONMENTS: "OrderedDict[Tuple[str, float], Any]" = OrderedDict()
_KEPT_ENVIRONMENTS = 8


def _environment(env: EnvLike) -> Optional["Environment"]:
    """The native environment of what ``env=`` takes."""
    if env is None or isinstance(env, Environment):
        return env
    if isinstance(env, np.ndarray):
        return Environment.from_array(np.ascontiguousarray(env, dtype=np.float32))
    if isinstance(env, (str, os.PathLike)):
        spec = os.fspath(env)
        try:
            stamp = os.stat(spec).st_mtime
        except OSError:
            stamp = 0.0
        key = (spec, stamp)
        made = _ENVIRONMENTS.get(key)
        if made is None:
            made = Environment.from_spec(spec)
            _ENVIRONMENTS[key] = made
            while len(_ENVIRONMENTS) > _KEPT_ENVIRONMENTS:
                _ENVIRONMENTS.popitem(last=False)
        else:
            _ENVIRONMENTS.move_to_end(key)
        return made
    raise TypeError(
        f"env: a file, a bundled map's name, 'sun:ELEV,AZIM', an (H, W, 3) array or an "
        f"Environment, not {type(env).__name__}"
    )


def _in_notebook() -> bool:
    shell = sys.modules.get("IPython")
    if shell is None:
        return False
    ip = shell.get_ipython() if hasattr(shell, "get_ipython") else None
    return ip is not None and type(ip).__name__ == "ZMQInteractiveShell"


class _Bar:
    """A progress bar: tqdm's (in a notebook, its widget) when tqdm is installed, else a line
    on stderr redrawn in place."""

    def __init__(self, what: str):
        self.what = what
        self.bar = None
        self.shown = -1
        try:
            from tqdm.auto import tqdm

            self.bar = tqdm(desc=what, unit="px", dynamic_ncols=True)
        except ImportError:
            pass

    def __call__(self, done: int, total: int) -> None:
        if self.bar is not None:
            if self.bar.total != total:
                self.bar.reset(total=total)
            self.bar.n = done
            self.bar.refresh()
            return
        percent = 100 * done // max(total, 1)
        if percent != self.shown:
            self.shown = percent
            sys.stderr.write(f"\r{self.what}: {done}/{total} ({percent}%)")
            sys.stderr.flush()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        elif self.shown >= 0:
            sys.stderr.write("\n")


def _progress(progress: ProgressLike, what: str):
    """The callable and bar of a ``progress=`` argument."""
    if callable(progress):
        return progress, None
    show = progress if progress is not None else (sys.stderr.isatty() or _in_notebook())
    if not show:
        return None, None
    bar = _Bar(what)
    return bar, bar


def bake_defaults() -> Dict[str, Any]:
    """The bake's settings with every flag at its default, as the engine stores them
    (``cube_n`` is ``--cube``)."""
    return json.loads(_native.default_settings())


def _shard(shard: Union[None, str, Sequence[int]]) -> Optional[List[int]]:
    if shard is None:
        return None
    if isinstance(shard, str):
        index, _, count = shard.partition("/")
        try:
            return [int(index), int(count)]
        except ValueError:
            raise ValueError(f"shard: `{shard}`; expected I/COUNT, e.g. 0/4") from None
    if len(shard) != 2:
        raise ValueError(f"shard: {shard!r}; expected (I, COUNT), e.g. (0, 4)")
    return [int(shard[0]), int(shard[1])]


def bake(
    scene: Union[str, "os.PathLike[str]"],
    out: Union[str, "os.PathLike[str]"],
    *,
    camera: Optional[str] = None,
    width: Optional[int] = None,
    height: Optional[int] = None,
    read_outside_folder: bool = False,
    cube: int = 32,
    spp: int = 1,
    edge_spp: int = 4,
    texel_samples: int = 1,
    edge_texel_samples: int = 9,
    light_samples: int = 64,
    unshadowed: bool = False,
    seed: int = 1,
    bounces: int = 0,
    paths: int = 256,
    bounce_visibility: str = "cache",
    cache_spacing: float = 4.0,
    sh_order: int = 6,
    threshold: float = 0.005,
    lossless: bool = False,
    budget: str = "l2",
    quantization: str = "q8",
    shard: Union[None, str, Sequence[int]] = None,
    per_vertex: bool = False,
    edge_length: Optional[float] = None,
    refine_shadows: bool = False,
    visibility: Optional[bool] = None,
    progress: ProgressLike = None,
) -> "Transport":
    """Bakes the scene file ``scene`` (TOML, or glTF) into the transport file ``out`` (.prt),
    as ``prt bake SCENE -o OUT`` does with the same flags, and opens it.

    The file is the command line's byte for byte. A file at ``out`` that already holds this
    very bake is kept, not baked again. Ctrl-C cancels the bake and leaves nothing at ``out``.

    Framing (glTF): ``camera`` by name, image ``width`` and ``height``; ``read_outside_folder``
    lets a glTF file read buffers and images outside its own folder.

    Sampling: ``cube`` (face size N, a power of two), ``spp``, ``edge_spp``, ``texel_samples``,
    ``edge_texel_samples``, ``light_samples``, ``unshadowed``, ``seed``, ``bounces``, ``paths``,
    ``bounce_visibility`` ("cache" or "exact"), ``cache_spacing``.

    Storage: ``sh_order`` (1 to 10), ``threshold``, ``lossless``, ``budget`` ("l2", "area",
    "sun", "absolute"), ``quantization`` ("q8", "q16"), ``shard`` ("I/COUNT" or (I, COUNT):
    one band of a bake, joined by :func:`merge`).

    Per vertex: ``per_vertex`` (one row per mesh vertex, so the camera can move),
    ``edge_length`` (default: the scene's, else 1/160 of its diagonal), ``refine_shadows``,
    ``visibility`` (keep each glossy vertex's visibility, its GGX lobe drawn per pixel; default,
    as the command line: for a scene with glossy materials).

    ``progress``: see :data:`ProgressLike`.
    """
    _bake_file(dict(locals()))
    return Transport.open(out)
    return Transport.open(out)


def _bake_file(a: Dict[str, Any]) -> None:
    """Bakes with the arguments of :func:`bake` (all of them, as a dict)."""
    default = {name: p.default for name, p in inspect.signature(bake).parameters.items()}
    if not a["per_vertex"]:
        for name in ("edge_length", "refine_shadows", "visibility"):
            if a[name] != default[name]:
                raise ValueError(f"{name} applies to per-vertex bakes: pass per_vertex=True")
    if a["lossless"]:
        for name in ("threshold", "budget", "quantization"):
            if a[name] != default[name]:
                raise ValueError(f"{name} cannot be used with lossless: it keeps every coefficient")
    stored = ("sh_order", "spp", "edge_spp", "texel_samples", "edge_texel_samples", "threshold",
              "budget", "quantization", "lossless", "unshadowed", "seed", "bounces", "paths",
              "bounce_visibility", "cache_spacing", "light_samples", "refine_shadows")
    settings = {name: a[name] for name in stored}
    settings["cube_n"] = a["cube"]
    settings["shard"] = _shard(a["shard"])
    scene, out = os.fspath(a["scene"]), os.fspath(a["out"])
    report, bar = _progress(a["progress"], f"baking {scene}")
    try:
        _native.bake(
            scene, out, json.dumps(settings), camera=a["camera"], width=a["width"],
            height=a["height"], read_outside_folder=a["read_outside_folder"],
            per_vertex=a["per_vertex"], edge_length=a["edge_length"],
            visibility=a["visibility"], progress=report,
        )
    finally:
        if bar is not None:
            bar.close()


def merge(shards: Sequence[Union[str, "os.PathLike[str]"]],
          out: Union[str, "os.PathLike[str]"]) -> "Transport":
    """Joins shard files (``bake(..., shard="I/COUNT")``, in any order) into ``out``, the file a
    single bake writes, byte for byte, as ``prt merge`` does, and opens it."""
    _native.merge([os.fspath(s) for s in shards], os.fspath(out))
    return Transport.open(out)


def read_image(path: Union[str, "os.PathLike[str]"]) -> np.ndarray:
    """Reads an OpenEXR image (``prt relight -o x.exr``) as a float32 (H, W, 3) array."""
    return _native.read_image(os.fspath(path))


def save_image(path: Union[str, "os.PathLike[str]"], image: np.ndarray,
               exposure: Optional[float] = None) -> None:
    """Writes an (H, W, 3) array as ``.exr`` (linear floats) or ``.png`` (tone-mapped at
    ``exposure`` stops, automatic by default), atomically."""
    _native.save_image(os.fspath(path), np.ascontiguousarray(image, dtype=np.float32), exposure)


def compare(image: np.ndarray, reference: np.ndarray,
            mask: Optional[np.ndarray] = None) -> Dict[str, float]:
    """Every error metric of ``image`` against ``reference`` (both (H, W, 3)) over the pixels
    where ``mask`` (H, W) is above 0, all of them without one: ``rel_l2`` (relative L2),
    ``rmse``, ``psnr_db``, ``rel_h1`` (relative L2 of the gradients) and ``dssim``, as
    ``prt compare`` prints them."""
    as_image = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
    flat = None if mask is None else np.ascontiguousarray(mask, dtype=np.float32).reshape(-1)
    rel_l2, rmse, psnr_db, rel_h1, dssim = _native.compare(as_image(image), as_image(reference),
                                                           flat)
    return {"rel_l2": rel_l2, "rmse": rmse, "psnr_db": psnr_db, "rel_h1": rel_h1, "dssim": dssim}


def _vec3(name: str, v: Optional[Sequence[float]]) -> Optional[List[float]]:
    if v is None:
        return None
    if len(v) != 3:
        raise ValueError(f"{name}: {v!r}; expected X, Y, Z")
    return [float(x) for x in v]


def _light_args(lights: Union[None, Mapping[str, Any], Sequence[str]]) -> List[str]:
    """``--light`` arguments from a dict (NAME: scale, NAME: (R, G, B), "NAME@POS": value) or a
    list of ``NAME=VALUE`` strings."""
    if lights is None:
        return []
    if isinstance(lights, Mapping):
        args = []
        for name, value in lights.items():
            if isinstance(value, (list, tuple, np.ndarray)):
                value = ",".join(repr(float(v)) for v in value)
            elif value is None:
                args.append(str(name))
                continue
            args.append(f"{name}={value}")
        return args
    if isinstance(lights, str):
        return [lights]
    return [str(a) for a in lights]


class Transport:
    """A transport file open for relighting, again and again: the last few environments and
    rotations stay prepared, so a sweep of K, methods or lights under one light prepares it
    once."""

    def __init__(self, native: Any, path: str):
        self._t = native
        self.path = path
        self._meta = json.loads(native.meta_json())

    @classmethod
    def open(cls, path: Union[str, "os.PathLike[str]"]) -> "Transport":
        """Opens a transport file (.prt)."""
        path = os.fspath(path)
        return cls(_native.Transport.open(path), path)

    def __repr__(self) -> str:
        kind = "per vertex" if self.per_vertex else f"{self.width} x {self.height} pixels"
        return f"Transport({self.path!r}, {kind}, N = {self.cube}, SH order {self.sh_order})"

    @property
    def meta(self) -> Dict[str, Any]:
        """The file's metadata as its JSON header holds it."""
        return copy.deepcopy(self._meta)

    @property
    def width(self) -> int:
        """Width of the image the rows light (a per-vertex bake's rows are laid out in one)."""
        return self._meta["width"]

    @property
    def height(self) -> int:
        """Height of that image."""
        return self._meta["height"]

    @property
    def cube(self) -> int:
        """Cube face size N: 6 N² Haar terms."""
        return self._meta["cube_n"]

    @property
    def sh_order(self) -> int:
        """The baked SH order n (n² coefficients)."""
        return self._meta["sh_order"]

    @property
    def per_vertex(self) -> bool:
        """Whether the rows are mesh vertices (the camera can move) rather than pixels."""
        return self._meta.get("per_vertex") is not None

    @property
    def lights(self) -> List[str]:
        """The names of the local lights baked in, in the file's order."""
        return [light["name"] for light in self._meta.get("lights", [])]

    @property
    def prepared(self) -> int:
        """How many environments and rotations have been prepared so far."""
        return self._t.prepared()

    def relight(
        self,
        env: EnvLike,
        method: str = "wavelet",
        terms: int = DEFAULT_TERMS,
        weighting: str = "transport",
        sh_order: Optional[int] = None,
        yaw: float = 0.0,
        pitch: float = 0.0,
        lights: Union[None, Mapping[str, Any], Sequence[str]] = None,
        background: str = "env",
        eye: Optional[Sequence[float]] = None,
        target: Optional[Sequence[float]] = None,
        up: Optional[Sequence[float]] = None,
        width: Optional[int] = None,
        height: Optional[int] = None,
        samples: int = 4,
    ) -> np.ndarray:
        """The image ``prt relight FILE --env ENV -o x.exr --device cpu`` writes with the same
        flags, as a float32 (H, W, 3) array: bit for bit the same values.

        ``env``: a file, a bundled map's name, ``"sun:ELEV,AZIM[,RADIUS]"``, an (H, W, 3)
        lat-long array, an :class:`Environment`, or ``None`` for the local lights alone.
        ``method``: "wavelet" (the ``terms`` largest Haar terms by ``weighting``: "transport",
        "area" or "none"), "sh" (SH of ``sh_order``, at most the baked one), "sh-light" (the
        light through SH, relit with every stored term) or "full" (every term).
        ``yaw``, ``pitch``: the environment turned about +Y, then +X, degrees.
        ``lights``: the local lights, ``{"lamp": 0.5, "key": (1, 0.8, 0.6), "spot@0.5": 1}`` or
        ``["lamp=0.5"]``; lights not named shine as the scene says.
        ``background``: "env" (the environment behind the scene) or "black".
        Per-vertex bakes: the camera ``eye``, ``target``, ``up`` (default: the scene's camera;
        a moved camera stays upright), image ``width``, ``height`` and ``samples`` a pixel (1,
        4 or 16).
        """
        return self._t.relight(
            _environment(env), method, terms, weighting, sh_order, float(yaw), float(pitch),
            _light_args(lights), background, _vec3("eye", eye), _vec3("target", target),
            _vec3("up", up), width, height, samples,
        )

    def time_relight(self, env: EnvLike, method: str = "wavelet", terms: int = DEFAULT_TERMS,
                     repeats: int = 20) -> np.ndarray:
        """The seconds of each of ``repeats`` relights timed inside the engine, without Python
        (transport-weighted, unturned, lights as the scene says, black background): the
        product that :meth:`relight` calls, to weigh what a call from Python adds."""
        return np.asarray(self._t.time_relight(_required_environment(env), method, terms,
                                               repeats))

    def coverage(self) -> np.ndarray:
        """How much of each pixel of the baked view sees geometry, 0 to 1, (H, W): the mask of
        :func:`compare`."""
        return self._t.coverage()

    def light_cube(self, env: EnvLike, yaw: float = 0.0, pitch: float = 0.0) -> np.ndarray:
        """The light exactly as the engine resamples it onto the transport's cube, a float32
        (6, N, N, 3) array (faces +X, -X, +Y, -Y, +Z, -Z; rows from the top)."""
        return self._t.cube(_required_environment(env), float(yaw), float(pitch))

    def haar(self, env: EnvLike, yaw: float = 0.0, pitch: float = 0.0) -> np.ndarray:
        """The light's 6 N² Haar coefficients, a float32 (6 N², 3) array: index j is the term
        index of :meth:`kept_terms` and of the rows of :meth:`row`."""
        haar, _ = self._t.light(_required_environment(env), float(yaw), float(pitch))
        return haar

    def sh_light(self, env: EnvLike, yaw: float = 0.0, pitch: float = 0.0) -> np.ndarray:
        """The light's SH coefficients at the baked order, a float64 (n², 3) array."""
        _, sh = self._t.light(_required_environment(env), float(yaw), float(pitch))
        return sh

    def kept_terms(
        self,
        env: EnvLike,
        terms: int = DEFAULT_TERMS,
        weighting: str = "transport",
        yaw: float = 0.0,
        pitch: float = 0.0,
    ) -> Tuple[np.ndarray, np.ndarray]:
        """The K terms a wavelet relight keeps: their indices (int64, (K,)) into
        :meth:`haar`, and their values (float32, (K, 3))."""
        return self._t.kept_terms(_required_environment(env), terms, weighting, float(yaw),
                                  float(pitch))

    def _pixel(self, pixel: Optional[Union[int, Tuple[int, int]]], vertex: Optional[int]) -> int:
        if (pixel is None) == (vertex is None):
            raise ValueError("give a pixel (an index, or (x, y)) or a vertex, not both")
        if vertex is not None:
            return self._t.vertex_pixel(int(vertex))
        if isinstance(pixel, tuple):
            x, y = pixel
            if not (0 <= x < self.width and 0 <= y < self.height):
                raise ValueError(f"pixel ({x}, {y}) is outside the {self.width} x {self.height} image")
            return int(y) * self.width + int(x)
        return int(pixel)

    def row(self, pixel: Optional[Union[int, Tuple[int, int]]] = None, *,
            vertex: Optional[int] = None) -> np.ndarray:
        """A pixel's (index or (x, y)) or a vertex's transport row, dense: a float32 (6 N², 3)
        array whose dot product with :meth:`haar` is the pixel's wavelet relight
        (``(t.row(p) * t.haar(env)).sum(0)``), before the local lights."""
        return self._t.row(self._pixel(pixel, vertex))

    def sh_row(self, pixel: Optional[Union[int, Tuple[int, int]]] = None, *,
               vertex: Optional[int] = None) -> np.ndarray:
        """The SH transport row of a pixel or a vertex, a float32 (n², 3) array: its dot
        product with :meth:`sh_light` is the pixel's SH relight."""
        return self._t.sh_row(self._pixel(pixel, vertex))


def _required_environment(env: EnvLike) -> "Environment":
    made = _environment(env)
    if made is None:
        raise ValueError("env: an environment is needed here")
    return made


from . import distributed  # noqa: E402  (Ray is imported when a distributed bake starts)
