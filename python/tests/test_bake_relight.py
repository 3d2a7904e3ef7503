"""The package against the command line: the same bakes byte for byte, the same images bit for
bit, and what it exposes of the light and the transport against the relight it explains."""

import numpy as np
import pytest

import wavelet_prt as wp
from conftest import SCENE, run, sky


@pytest.fixture
def baked(tmp_path, scene):
    """The test scene baked from Python at N = 8."""
    return wp.bake(scene, tmp_path / "py.prt", cube=8, sh_order=3)


@pytest.fixture
def sky_file(tmp_path):
    path = tmp_path / "sky.exr"
    wp.save_image(path, sky())
    return path


@pytest.mark.parametrize(
    "flags",
    [
        {"cube": 8, "sh_order": 3},
        {"cube": 8, "lossless": True, "edge_spp": 0},
        {"cube": 4, "per_vertex": True, "edge_length": 0.5},
        {"cube": 8, "shard": "1/3", "quantization": "q16", "width": 48, "height": 48},
    ],
    ids=["default", "lossless", "per-vertex", "shard"],
)
def test_a_bake_from_python_is_the_command_lines_file_byte_for_byte(prt, tmp_path, scene, flags):
    wp.bake(scene, tmp_path / "py.prt", **flags)
    args = []
    for name, value in flags.items():
        flag = "--" + name.replace("_", "-")
        args += [flag] if value is True else [flag, str(value)]
    run(prt, "bake", scene, "-o", tmp_path / "cli.prt", *args)
    assert (tmp_path / "py.prt").read_bytes() == (tmp_path / "cli.prt").read_bytes()


def test_the_bake_defaults_are_the_command_lines(prt):
    help_text = run(prt, "bake", "--help").stdout
    defaults = wp.bake_defaults()
    import inspect

    params = inspect.signature(wp.bake).parameters
    for name, param in params.items():
        if name in ("scene", "out", "progress"):
            continue
        flag = "--" + name.replace("_", "-")
        assert flag in help_text, f"{name} is no flag of prt bake"
        stored = defaults.get("cube_n" if name == "cube" else name, param.default)
        if param.default is not None and name in defaults or name == "cube":
            assert param.default == stored, f"{name}: {param.default} against {stored}"


@pytest.mark.parametrize(
    "method, extra",
    [
        ("wavelet", {"terms": 20}),
        ("wavelet", {"terms": 7, "weighting": "area"}),
        ("sh", {"sh_order": 2}),
        ("sh-light", {"sh_order": 4}),
        ("full", {}),
    ],
)
@pytest.mark.parametrize("turned", [False, True], ids=["still", "turned"])
@pytest.mark.parametrize("lit", [False, True], ids=["env", "env+light"])
def test_a_relight_is_the_command_lines_image_bit_for_bit(
    prt, tmp_path, baked, sky_file, method, extra, turned, lit
):
    kwargs = dict(extra)
    args = ["--method", method]
    for name, value in extra.items():
        args += ["--" + name.replace("_", "-"), str(value)]
    if turned:
        kwargs.update(yaw=30.0, pitch=-12.5)
        args += ["--yaw", "30", "--pitch=-12.5"]
    if lit:
        kwargs["lights"] = {"bulb": 0.5}
        args += ["--light", "bulb=0.5"]
    img = baked.relight(str(sky_file), method=method, **kwargs)
    run(prt, "relight", baked.path, "--env", sky_file, "-o", tmp_path / "cli.exr",
        "--device", "cpu", *args)
    cli = wp.read_image(tmp_path / "cli.exr")
    assert img.dtype == np.float32 and img.shape == (16, 24, 3)
    assert np.array_equal(img, cli)


def test_a_per_vertex_still_is_the_command_lines_image_bit_for_bit(prt, tmp_path, scene):
    t = wp.bake(scene, tmp_path / "v.prt", cube=4, per_vertex=True, edge_length=0.5)
    img = t.relight("sun:35,60", terms=30, eye=[2.0, 1.2, 3.0], target=[0, 0.4, 0], width=40,
                    height=30, lights={"bulb": (1.0, 0.5, 0.25)})
    run(prt, "relight", t.path, "--env", "sun:35,60", "--terms", "30", "--eye", "2,1.2,3",
        "--target", "0,0.4,0", "--width", "40", "--height", "30", "--light", "bulb=1,0.5,0.25",
        "-o", tmp_path / "cli.exr", "--device", "cpu")
    assert img.shape == (30, 40, 3)
    assert np.array_equal(img, wp.read_image(tmp_path / "cli.exr"))


def test_a_glossy_per_vertex_still_draws_the_lights_highlights_as_the_command_line(
        prt, tmp_path):
    # The sphere made glossy: its vertices keep their visibility and their share of the bulb,
    # whose highlight each pixel draws.
    text = SCENE.replace('type = "diffuse"\nalbedo = [0.8, 0.3, 0.2]',
                         'type = "glossy"\nalbedo = [0.4, 0.15, 0.1]\n'
                         'specular = [0.5, 0.5, 0.5]\nroughness = 0.2')
    assert text != SCENE
    scene = tmp_path / "glossy.toml"
    scene.write_text(text)
    t = wp.bake(scene, tmp_path / "g.prt", cube=4, per_vertex=True, edge_length=0.3)
    view = dict(eye=[2.0, 1.2, 3.0], target=[0, 0.4, 0], width=40, height=30)
    lit = t.relight("sun:35,60", terms=30, **view)
    run(prt, "relight", t.path, "--env", "sun:35,60", "--terms", "30", "--eye", "2,1.2,3",
        "--target", "0,0.4,0", "--width", "40", "--height", "30", "-o", tmp_path / "cli.exr",
        "--device", "cpu")
    assert np.array_equal(lit, wp.read_image(tmp_path / "cli.exr"))
    # The bulb's weight scales its diffuse light and its highlight alike: each step of it adds
    # as much, and its highlight is part of that.
    off = t.relight("sun:35,60", terms=30, lights={"bulb": 0}, **view)
    twice = t.relight("sun:35,60", terms=30, lights={"bulb": 2.0}, **view)
    assert np.abs(lit - off).max() > 0.0
    assert np.allclose(twice - lit, lit - off, rtol=1e-4, atol=1e-6)


def test_an_array_environment_is_the_same_map_read_from_exr(baked, sky_file):
    for method in ("wavelet", "sh", "full"):
        from_file = baked.relight(str(sky_file), method=method)
        from_array = baked.relight(sky(), method=method)
        assert np.array_equal(from_file, from_array)
    env = wp.Environment.from_array(sky())
    assert np.array_equal(env.pixels(), sky())


def test_relighting_again_under_one_environment_prepares_it_once(baked):
    env = wp.Environment.from_spec("sun:30,40")
    for k in (1, 10, 100, 384):
        baked.relight(env, terms=k)
    baked.relight(env, method="sh")
    assert baked.prepared == 1
    baked.relight(env, yaw=10)
    assert baked.prepared == 2


def test_a_pixels_row_times_the_haar_light_is_its_full_relight(baked):
    img = baked.relight(sky(), method="full", lights={"bulb": 0}, background="black")
    haar = baked.haar(sky())
    assert haar.shape == (6 * 8 * 8, 3)
    lit = [(x, y) for y in range(16) for x in range(24) if img[y, x].sum() > 0]
    assert len(lit) > 100
    for x, y in lit[::37]:
        row = baked.row((x, y))
        assert row.shape == (384, 3)
        np.testing.assert_allclose((row.astype(np.float64) * haar).sum(0), img[y, x],
                                   rtol=2e-4, atol=1e-6)


def test_a_pixels_sh_row_times_the_sh_light_is_its_sh_relight(baked):
    img = baked.relight(sky(), method="sh", lights={"bulb": 0}, background="black")
    sh = baked.sh_light(sky())
    assert sh.shape == (9, 3) and sh.dtype == np.float64
    for x, y in [(12, 10), (3, 14), (20, 4)]:
        np.testing.assert_allclose((baked.sh_row((x, y)) * sh).sum(0), img[y, x],
                                   rtol=2e-4, atol=1e-6)


def test_the_kept_terms_are_the_largest_of_the_haar_light(baked):
    haar = baked.haar(sky())
    indices, values = baked.kept_terms(sky(), terms=25, weighting="none")
    assert indices.shape == (25,) and values.shape == (25, 3)
    assert len(set(indices.tolist())) == 25
    np.testing.assert_array_equal(values, haar[indices])
    # Unweighted, no dropped term is larger than the smallest kept one, by the magnitude the
    # engine ranks by: the luminance of the channels' absolute values.
    size = np.abs(haar) @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    dropped = np.setdiff1d(np.arange(len(haar)), indices)
    assert size[dropped].max() <= size[indices].min() * (1 + 1e-6)


def test_the_light_cube_of_a_uniform_sky_is_uniform(baked):
    grey = np.full((16, 32, 3), 0.75, dtype=np.float32)
    cube = baked.light_cube(grey)
    assert cube.shape == (6, 8, 8, 3)
    np.testing.assert_allclose(cube, 0.75, rtol=1e-5)


def test_the_metadata_is_the_files(baked):
    assert baked.cube == 8 and baked.sh_order == 3 and not baked.per_vertex
    assert baked.lights == ["bulb"]
    assert baked.meta["width"] == 24 and baked.meta["height"] == 16
    assert baked.coverage().shape == (16, 24)


def test_compare_reports_the_command_lines_metrics(prt, tmp_path, baked):
    a = baked.relight("sun:30,40", terms=10, background="black")
    b = baked.relight("sun:30,40", method="full", background="black")
    wp.save_image(tmp_path / "a.exr", a)
    wp.save_image(tmp_path / "b.exr", b)
    m = wp.compare(a, b)
    out = run(prt, "compare", tmp_path / "a.exr", tmp_path / "b.exr").stdout
    assert 0 < m["rel_l2"] < 1
    assert f"rel_l2 {100 * m['rel_l2']:.4f}%" in out, out
    assert f"psnr {m['psnr_db']:.2f} dB" in out, out
    assert wp.compare(b, b)["rel_l2"] == 0
