//! `wavelet_prt._native`: the Python bindings of the engine's front door (`wavelet_prt::api`)
//! and nothing below it. The Python package (`wavelet_prt/__init__.py`) gives these their
//! keyword names and defaults, which are the command line's; here each call checks its
//! arguments through the facade, releases the GIL for the work, and hands images back as numpy
//! arrays that own the engine's buffers (no copy).

use numpy::{PyArray1, PyArray2, PyArray3, PyArrayMethods, PyReadonlyArray1, PyReadonlyArray3};
use pyo3::exceptions::{PyFileNotFoundError, PyKeyboardInterrupt, PyOSError, PyValueError};
use pyo3::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;
use wavelet_prt::PrtError;
use wavelet_prt::api::{self, BakeProgress, BakeSettings, Cancel, Framing, Image, Still, Terms};

/// Two arrays handed back together.
type Arrays<'py, A, B> = (Bound<'py, A>, Bound<'py, B>);

/// How often a bake in progress looks for Ctrl-C and reports its progress.
const POLL: Duration = Duration::from_millis(50);

/// The engine's error as Python's: a file the system could not read or write is an `OSError`
/// (`FileNotFoundError` when missing), a cancelled bake a `KeyboardInterrupt`, anything else a
/// `ValueError`; the message is the command line's.
fn py_err(e: PrtError) -> PyErr {
    match &e {
        PrtError::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(e.to_string())
        }
        PrtError::Io { .. } => PyOSError::new_err(e.to_string()),
        PrtError::Cancelled => PyKeyboardInterrupt::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// `Result` of the engine to `PyResult`.
trait OrPy<T> {
    fn py(self) -> PyResult<T>;
}

impl<T> OrPy<T> for wavelet_prt::Result<T> {
    fn py(self) -> PyResult<T> {
        self.map_err(py_err)
    }
}

/// A name of the command line parsed as the command line parses it (`"wavelet"`, `"area"`).
fn parse<T: std::str::FromStr<Err = PrtError>>(s: &str) -> PyResult<T> {
    s.parse().map_err(py_err)
}

/// Values in an (rows, 3) float32 array, without a copy.
fn rgb_rows<'py>(py: Python<'py>, v: Vec<[f32; 3]>) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let rows = v.len();
    PyArray1::from_vec(py, bytemuck::cast_vec::<[f32; 3], f32>(v)).reshape([rows, 3])
}

/// An image as an (H, W, 3) float32 array, without a copy.
fn image_array(py: Python<'_>, image: Image) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let (w, h) = (image.width, image.height);
    PyArray1::from_vec(py, bytemuck::cast_vec::<[f32; 3], f32>(image.pixels)).reshape([h, w, 3])
}

/// An (H, W, 3) array as an image.
fn array_image(a: &PyReadonlyArray3<'_, f32>) -> PyResult<Image> {
    let view = a.as_array();
    let (height, width, c) = view.dim();
    if c != 3 {
        return Err(PyValueError::new_err(format!(
            "an image is an array of shape (H, W, 3); this one is ({height}, {width}, {c})"
        )));
    }
    let pixels = view
        .outer_iter()
        .flat_map(|row| {
            row.outer_iter()
                .map(|p| [p[0], p[1], p[2]])
                .collect::<Vec<_>>()
        })
        .collect();
    Ok(Image {
        width,
        height,
        pixels,
    })
}

/// Bakes the scene file `scene` into the transport file `out`, as `prt bake` does: `settings`
/// is a JSON object of `BakeSettings` (the keys the command line's flags, `_` for `-`), the
/// framing that of a glTF file. `progress(done, total)` is called as the rows are made; Ctrl-C
/// (or an exception from `progress`) cancels the bake, leaving nothing at `out`. A file that
/// already holds this bake is kept ([`api::bake_to_file`]). Returns the file's metadata as JSON.
#[pyfunction]
#[pyo3(signature = (scene, out, settings, camera=None, width=None, height=None, read_outside_folder=false, per_vertex=false, edge_length=None, visibility=None, progress=None))]
#[allow(clippy::too_many_arguments)] // the keywords of `prt bake`, named one by one from Python
fn bake(
    py: Python<'_>,
    scene: PathBuf,
    out: PathBuf,
    settings: &str,
    camera: Option<String>,
    width: Option<u32>,
    height: Option<u32>,
    read_outside_folder: bool,
    per_vertex: bool,
    edge_length: Option<f32>,
    visibility: Option<bool>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let mut settings: BakeSettings = serde_json::from_str(settings)
        .map_err(|e| PyValueError::new_err(format!("bake settings: {e}")))?;
    let framing = Framing {
        camera,
        width,
        height,
        read_outside_folder,
    };
    let scene = py.detach(|| api::load_scene(&scene, &framing)).py()?;
    if per_vertex {
        settings.domain = api::vertices(&scene, edge_length);
        settings.visibility = visibility.unwrap_or_else(|| api::glossy_visibility(&scene));
    }
    let (done, total) = (AtomicUsize::new(0), AtomicUsize::new(0));
    let cancel = Cancel::new();
    let on_progress = |p: BakeProgress| {
        done.store(p.pixels_done, Ordering::Relaxed);
        total.store(p.pixels_total, Ordering::Relaxed);
    };
    let mut raised: Option<PyErr> = None;
    let baked = py.detach(|| {
        std::thread::scope(|s| {
            let work =
                s.spawn(|| api::bake_to_file(&scene, &settings, &out, &on_progress, &cancel));
            let mut reported = (usize::MAX, usize::MAX);
            while !work.is_finished() {
                std::thread::sleep(POLL);
                if raised.is_some() {
                    continue;
                }
                Python::attach(|py| {
                    let now = (done.load(Ordering::Relaxed), total.load(Ordering::Relaxed));
                    let called = match (&progress, now != reported) {
                        (Some(f), true) => f.bind(py).call1(now).map(|_| ()),
                        _ => Ok(()),
                    };
                    reported = now;
                    if let Err(e) = py.check_signals().and(called) {
                        cancel.cancel();
                        raised = Some(e);
                    }
                });
            }
            work.join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
        })
    });
    if let Some(e) = raised {
        return Err(e);
    }
    let meta = baked.py()?;
    if let Some(f) = &progress {
        let total = total.load(Ordering::Relaxed);
        f.bind(py).call1((total, total))?;
    }
    meta_json(&meta)
}

/// A transport's metadata as the file's JSON header holds it.
fn meta_json(meta: &api::TransportMeta) -> PyResult<String> {
    serde_json::to_string(meta).map_err(|e| PyValueError::new_err(format!("metadata: {e}")))
}

/// The settings of a bake with every flag at its default, as JSON.
#[pyfunction]
fn default_settings() -> PyResult<String> {
    serde_json::to_string(&BakeSettings::default())
        .map_err(|e| PyValueError::new_err(e.to_string()))
}

/// Joins shard files into the file a single bake writes; returns its metadata as JSON.
#[pyfunction]
fn merge(py: Python<'_>, shards: Vec<PathBuf>, out: PathBuf) -> PyResult<String> {
    let meta = py.detach(|| api::merge(&shards, &out, &|_, _| {})).py()?;
    meta_json(&meta)
}

/// Reads an OpenEXR image as an (H, W, 3) float32 array.
#[pyfunction]
fn read_image(py: Python<'_>, path: PathBuf) -> PyResult<Bound<'_, PyArray3<f32>>> {
    let image = py.detach(|| api::read_image(&path)).py()?;
    image_array(py, image)
}

/// Writes an (H, W, 3) array as `.exr` (linear) or `.png` (tone-mapped at `exposure` stops,
/// automatic by default).
#[pyfunction]
#[pyo3(signature = (path, image, exposure=None))]
fn save_image(
    py: Python<'_>,
    path: PathBuf,
    image: PyReadonlyArray3<'_, f32>,
    exposure: Option<f32>,
) -> PyResult<()> {
    let image = array_image(&image)?;
    py.detach(|| api::save_image(&image, &path, exposure, None))
        .py()
}

/// Every error metric of `image` against `reference` over the pixels where `mask` (H·W values)
/// is above 0: (relative L2, RMSE, PSNR in dB, relative gradient L2, DSSIM).
#[pyfunction]
#[pyo3(signature = (image, reference, mask=None))]
fn compare(
    image: PyReadonlyArray3<'_, f32>,
    reference: PyReadonlyArray3<'_, f32>,
    mask: Option<PyReadonlyArray1<'_, f32>>,
) -> PyResult<(f64, f64, f64, f64, f64)> {
    let (a, r) = (array_image(&image)?, array_image(&reference)?);
    let mask = mask.map(|m| m.as_array().to_vec());
    let e = api::compare(&a, &r, mask.as_deref()).py()?;
    Ok((e.rel_l2, e.rmse, e.psnr_db, e.rel_h1, e.dssim))
}

/// A lat-long environment map, loaded and checked once: relighting again with the same one
/// prepares nothing again.
#[pyclass(module = "wavelet_prt._native", frozen)]
struct Environment {
    inner: api::Environment,
}

#[pymethods]
impl Environment {
    /// What `--env` takes: a `.exr`/`.hdr` file, a bundled map by name, or
    /// `sun:ELEV,AZIM[,RADIUS]`.
    #[staticmethod]
    fn from_spec(py: Python<'_>, spec: &str) -> PyResult<Environment> {
        let inner = py.detach(|| api::Environment::from_spec(spec)).py()?;
        Ok(Environment { inner })
    }

    /// An (H, W, 3) array of linear radiance, rows from the zenith down.
    #[staticmethod]
    fn from_array(pixels: PyReadonlyArray3<'_, f32>) -> PyResult<Environment> {
        let image = array_image(&pixels)?;
        let inner = api::Environment::from_array(image.width, image.height, image.pixels).py()?;
        Ok(Environment { inner })
    }

    /// The map's pixels as an (H, W, 3) array (a copy).
    fn pixels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let map = self.inner.map();
        image_array(
            py,
            Image {
                width: map.width,
                height: map.height,
                pixels: map.pixels.clone(),
            },
        )
    }

    /// Where it came from: a file, a bundled map, the sun's description, or "array".
    #[getter]
    fn source(&self) -> String {
        self.inner.source().to_string()
    }

    fn __repr__(&self) -> String {
        let m = self.inner.map();
        format!(
            "Environment({:?}, {} x {})",
            self.inner.source(),
            m.width,
            m.height
        )
    }
}

/// A transport file open for relighting, again and again: the last few environments and
/// rotations stay prepared.
#[pyclass(module = "wavelet_prt._native")]
struct Transport {
    inner: api::Relighter,
}

/// The kept-terms half of a request, parsed.
fn request(
    t: &api::Transport,
    method: &str,
    terms: usize,
    weighting: &str,
    sh_order: Option<usize>,
) -> PyResult<api::RelightRequest> {
    api::request(&t.meta, parse(method)?, terms, parse(weighting)?, sh_order).py()
}

#[pymethods]
impl Transport {
    /// Opens a transport file.
    #[staticmethod]
    fn open(py: Python<'_>, path: PathBuf) -> PyResult<Transport> {
        let inner = py
            .detach(|| api::open(&path).and_then(api::Relighter::new))
            .py()?;
        Ok(Transport { inner })
    }

    /// The metadata as the file's JSON header holds it.
    fn meta_json(&self) -> PyResult<String> {
        meta_json(&self.inner.transport().meta)
    }

    /// The image `prt relight --device cpu` writes, as an (H, W, 3) array.
    #[pyo3(signature = (env, method, terms, weighting, sh_order, yaw, pitch, lights, background, eye, target, up, width, height, samples))]
    #[allow(clippy::too_many_arguments)] // the keywords of `prt relight`, named one by one
    fn relight<'py>(
        &mut self,
        py: Python<'py>,
        env: Option<PyRef<'py, Environment>>,
        method: &str,
        terms: usize,
        weighting: &str,
        sh_order: Option<usize>,
        yaw: f64,
        pitch: f64,
        lights: Vec<String>,
        background: &str,
        eye: Option<[f32; 3]>,
        target: Option<[f32; 3]>,
        up: Option<[f32; 3]>,
        width: Option<u32>,
        height: Option<u32>,
        samples: u32,
    ) -> PyResult<Bound<'py, PyArray3<f32>>> {
        let req = request(self.inner.transport(), method, terms, weighting, sh_order)?;
        let rotation = api::rotation(yaw, pitch).py()?;
        let mix = self.inner.light_args(&lights).py()?;
        self.inner.set_background(parse(background)?);
        let still = Still {
            eye: eye.map(Into::into),
            target: target.map(Into::into),
            up: up.map(Into::into),
            width,
            height,
        };
        let env = env.map(|e| e.inner.clone());
        let inner = &mut self.inner;
        let image = py
            .detach(|| inner.render(env.as_ref(), &req, rotation, &mix, &still, samples))
            .py()?;
        image_array(py, image)
    }

    /// The seconds of each of `repeats` relights of `env` by `method` with `terms` kept terms
    /// (transport-weighted, the environment unturned, the local lights as the scene says, the
    /// background black, a per-pixel bake's view or a per-vertex bake's vertex colours), each
    /// timed inside Rust from the request to the finished image: the product without Python,
    /// to weigh what a call from Python adds.
    fn time_relight(
        &mut self,
        py: Python<'_>,
        env: PyRef<'_, Environment>,
        method: &str,
        terms: usize,
        repeats: usize,
    ) -> PyResult<Vec<f64>> {
        let env = env.inner.clone();
        let inner = &mut self.inner;
        let method = parse(method)?;
        let weighting = parse("transport")?;
        inner.set_background(api::Background::Black);
        py.detach(|| {
            (0..repeats)
                .map(|_| {
                    let start = std::time::Instant::now();
                    let req =
                        api::request(&inner.transport().meta, method, terms, weighting, None)?;
                    let mix = inner.light_args(&[] as &[&str])?;
                    let rotation = api::rotation(0.0, 0.0)?;
                    inner.render(Some(&env), &req, rotation, &mix, &Still::default(), 4)?;
                    Ok(start.elapsed().as_secs_f64())
                })
                .collect::<wavelet_prt::Result<Vec<f64>>>()
        })
        .py()
    }

    /// How much of each pixel of the baked view sees geometry, an (H, W) array.
    fn coverage<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let t = self.inner.transport();
        let (w, h) = (t.meta.width as usize, t.meta.height as usize);
        PyArray1::from_slice(py, self.inner.coverage()).reshape([h, w])
    }

    /// The light's cube as the relight resamples it, a (6, N, N, 3) array.
    fn cube<'py>(
        &self,
        py: Python<'py>,
        env: PyRef<'py, Environment>,
        yaw: f64,
        pitch: f64,
    ) -> PyResult<Bound<'py, numpy::PyArray4<f32>>> {
        let rotation = api::rotation(yaw, pitch).py()?;
        let env = env.inner.clone();
        let cube = py.detach(|| self.inner.cube(&env, rotation)).py()?;
        let n = cube.n;
        PyArray1::from_vec(py, bytemuck::cast_vec::<[f32; 3], f32>(cube.texels))
            .reshape([6, n, n, 3])
    }

    /// The light's 6 N² Haar coefficients, a (6 N², 3) array, and its SH coefficients at the
    /// baked order, an (n², 3) float64 array.
    fn light<'py>(
        &mut self,
        py: Python<'py>,
        env: PyRef<'py, Environment>,
        yaw: f64,
        pitch: f64,
    ) -> PyResult<Arrays<'py, PyArray2<f32>, PyArray2<f64>>> {
        let rotation = api::rotation(yaw, pitch).py()?;
        let env = env.inner.clone();
        let inner = &mut self.inner;
        let (haar, sh) = py
            .detach(|| {
                inner
                    .light(&env, rotation)
                    .map(|l| (l.wavelet.coeffs.clone(), l.sh.clone()))
            })
            .py()?;
        let shc = sh.len();
        let sh =
            PyArray1::from_vec(py, bytemuck::cast_vec::<[f64; 3], f64>(sh)).reshape([shc, 3])?;
        Ok((rgb_rows(py, haar)?, sh))
    }

    /// The K terms a wavelet relight keeps under `env` by `weighting`: their Haar indices
    /// (int64) and RGB values.
    fn kept_terms<'py>(
        &mut self,
        py: Python<'py>,
        env: PyRef<'py, Environment>,
        terms: usize,
        weighting: &str,
        yaw: f64,
        pitch: f64,
    ) -> PyResult<Arrays<'py, PyArray1<i64>, PyArray2<f32>>> {
        let req = request(self.inner.transport(), "wavelet", terms, weighting, None)?;
        let rotation = api::rotation(yaw, pitch).py()?;
        let env = env.inner.clone();
        let inner = &mut self.inner;
        let terms = py.detach(|| inner.terms(&env, &req, rotation)).py()?;
        let Terms::Wavelet(kept) = terms else {
            return Err(PyValueError::new_err("a wavelet request gives Haar terms"));
        };
        let indices = kept.indices.iter().map(|&i| i as i64).collect();
        Ok((PyArray1::from_vec(py, indices), rgb_rows(py, kept.values)?))
    }

    /// Pixel `pixel`'s dense transport row, a (6 N², 3) array.
    fn row<'py>(&self, py: Python<'py>, pixel: usize) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let row = py.detach(|| self.inner.row(pixel)).py()?;
        rgb_rows(py, row)
    }

    /// Pixel `pixel`'s SH transport row, an (n², 3) array.
    fn sh_row<'py>(&self, py: Python<'py>, pixel: usize) -> PyResult<Bound<'py, PyArray2<f32>>> {
        rgb_rows(py, self.inner.sh_row(pixel).py()?)
    }

    /// The pixel of vertex `vertex`'s rows in a per-vertex bake.
    fn vertex_pixel(&self, vertex: usize) -> PyResult<usize> {
        self.inner.vertex_pixel(vertex).py()
    }

    /// How many environments and rotations it has prepared so far.
    fn prepared(&self) -> usize {
        self.inner.prepared()
    }
}

/// The native half of the `wavelet_prt` package.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(bake, m)?)?;
    m.add_function(wrap_pyfunction!(default_settings, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(read_image, m)?)?;
    m.add_function(wrap_pyfunction!(save_image, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_class::<Environment>()?;
    m.add_class::<Transport>()?;
    m.add("DEFAULT_TERMS", api::DEFAULT_TERMS)?;
    m.add("VERSION", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
