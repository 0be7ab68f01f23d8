//! `lumis._lumis`: the Python extension module behind the `lumis` package (python/lumis/).
//!
//! Scenes are loaded and built by lumis-core exactly as the CLI does, renders run on a Rust
//! thread with the GIL released while the calling thread polls for Python signals (so Ctrl-C in a
//! notebook cancels the render), and the output files are written by
//! [`lumis_core::render_files`], the CLI's own writer. No panic reaches Python: every entry point
//! catches unwinding and raises a `lumis.LumisError` instead.
//!
//! Why one file of over 600 lines: the extension module's Python classes and their conversions are
//! one PyO3 module (its `study` part is in study.rs).

mod convert;
mod study;

use lumis::embedding::catch_panic;
use lumis_core::budgets::Budgets;
use lumis_core::error_estimate::Metric;
use lumis_core::film::Film;
use lumis_core::image_io::Metadata;
use lumis_core::params::ParamSpec;
use lumis_core::passes::{History, Request, Settings};
use lumis_core::progressive::{Control, RenderState, Scope};
use lumis_core::registry::{
    self, BsdfPlugin, EmitterPlugin, IntegratorPlugin, PluginInfo, TexturePlugin,
};
use lumis_core::render::RenderStats;
use lumis_core::scene::description::{PluginSpec, SceneDescription};
use lumis_core::{render_files, scene};
use numpy::ndarray::Array3;
use numpy::{IntoPyArray, PyArray3};
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyKeyError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError, mpsc};
use std::time::{Duration, Instant};

create_exception!(
    lumis,
    LumisError,
    PyException,
    "Base class of every error lumis raises."
);
create_exception!(
    lumis,
    SceneError,
    LumisError,
    "A problem with a scene or a file it refers to; `str()` is the CLI's `file[:line:col]: message`."
);
create_exception!(
    lumis,
    PluginError,
    LumisError,
    "An unknown plugin, or parameters a plugin refuses (given to `Scene.render`)."
);
create_exception!(
    lumis,
    RenderError,
    LumisError,
    "The render could not run (threads could not start, or an internal error)."
);
create_exception!(
    lumis,
    OutputError,
    LumisError,
    "An output file could not be written."
);

/// How often the calling thread wakes up during a render to let Python handle signals.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Runs an entry point's body so that a panic becomes a `LumisError`.
fn guarded<T>(f: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    catch_panic(f).unwrap_or_else(|message| Err(LumisError::new_err(message)))
}

/// What the work thread of [`beside_python`] sends the calling thread.
enum Event<T> {
    /// The work's result.
    Done(Result<T, String>),
    /// A pass of a render in passes is done: its report, and where to answer whether to go on.
    Pass(PassReport, mpsc::Sender<bool>),
}

/// Runs `work` on a thread named `name` while the calling thread waits with the GIL released,
/// waking every [`SIGNAL_POLL`] to let Python handle signals and to call `tick`. `work` may hand
/// a pass's report to the calling thread, which calls `on_pass` with it (the GIL held) and
/// answers whether to go on; `work` waits for the answer. Ctrl-C (any signal handler that
/// raises) or an exception from `tick` or `on_pass` sets the cancel flag `work` is given (and
/// answers a waiting pass "stop"), waits for the thread to stop (within a camera sample per
/// render thread) and is returned; a panic in `work` becomes a `LumisError`.
fn beside_python<T: Send + 'static>(
    py: Python<'_>,
    name: &str,
    work: impl FnOnce(&AtomicBool, &dyn Fn(PassReport) -> bool) -> T + Send + 'static,
    mut tick: impl FnMut() -> PyResult<()>,
    mut on_pass: impl FnMut(PassReport) -> PyResult<bool>,
) -> PyResult<T> {
    let cancel = Arc::new(AtomicBool::new(false));
    let (sender, receiver) = mpsc::channel::<Event<T>>();
    let thread_cancel = cancel.clone();
    let worker = std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let passes = sender.clone();
            let report = move |report: PassReport| {
                let (answer, answered) = mpsc::channel();
                // No answer (the caller stopped waiting) is a stop.
                passes.send(Event::Pass(report, answer)).is_ok() && answered.recv() == Ok(true)
            };
            let outcome = catch_panic(|| work(&thread_cancel, &report));
            // The receiver is gone only if the caller stopped waiting (interrupted).
            let _ = sender.send(Event::Done(outcome));
        })
        .map_err(|e| RenderError::new_err(format!("cannot start the thread `{name}`: {e}")))?;
    // `detach` needs a shareable receiver; only this thread ever locks it.
    let receiver = Mutex::new(receiver);
    let finished = loop {
        let received = py.detach(|| {
            receiver
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .recv_timeout(SIGNAL_POLL)
        });
        match received {
            Ok(Event::Done(outcome)) => break Ok(outcome),
            Ok(Event::Pass(report, answer)) => match on_pass(report) {
                Ok(go_on) => {
                    let _ = answer.send(go_on);
                }
                Err(raised) => break Err(raised),
            },
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if let Err(raised) = py.check_signals().and_then(|()| tick()) {
                    break Err(raised);
                }
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                break Ok(Err(format!("the thread `{name}` stopped without a result")));
            }
        }
    };
    if finished.is_err() {
        cancel.store(true, Ordering::Relaxed);
    }
    // A pass waiting for its answer gets none when the receiver goes: a stop.
    drop(receiver);
    let _ = py.detach(|| worker.join());
    finished?.map_err(LumisError::new_err)
}

/// `lumis.SceneError` carrying the CLI's message and the file and position as attributes.
fn scene_error(py: Python<'_>, e: &lumis_core::error::SceneError) -> PyErr {
    let err = SceneError::new_err(e.to_string());
    let value = err.value(py);
    let (line, column) = e.position.unzip();
    // Setting attributes on a fresh exception object cannot fail short of memory exhaustion,
    // which Python reports itself.
    let _ = value.setattr("file", e.file.display().to_string());
    let _ = value.setattr("line", line);
    let _ = value.setattr("column", column);
    let _ = value.setattr("message", e.message.clone());
    err
}

fn output_error(py: Python<'_>, e: &lumis_core::image_io::OutputError) -> PyErr {
    let err = OutputError::new_err(e.to_string());
    let _ = err.value(py).setattr("path", e.path.display().to_string());
    err
}

/// A built scene, ready to render any number of times.
#[pyclass(module = "lumis", frozen)]
struct Scene {
    /// The scene as the user named it (the path as given, or `<dict>`): the EXR's `scene`.
    label: String,
    /// The path messages and relative asset paths go by.
    path: PathBuf,
    description: SceneDescription,
    /// Renders of one scene run one at a time: each sets the scene's spp and seed.
    built: Arc<Mutex<scene::Scene>>,
    load_time: f64,
}

fn build(
    py: Python<'_>,
    label: String,
    path: PathBuf,
    description: SceneDescription,
) -> PyResult<Scene> {
    let start = Instant::now();
    let loaded = py
        .detach(|| catch_panic(|| scene::load::build_scene(description, &path)))
        .map_err(LumisError::new_err)?
        .map_err(|e| scene_error(py, &e))?;
    Ok(Scene {
        label,
        path,
        description: loaded.description,
        built: Arc::new(Mutex::new(loaded.scene)),
        load_time: start.elapsed().as_secs_f64(),
    })
}

/// Reads, parses and builds the RON scene at `path`, as `lumis render` does.
///
/// overrides: as `--set`, a dict {"film.width": 64, "integrator.type": "alpha"} or a list of
/// "path=value" strings. Raises SceneError with the CLI's `file[:line:col]: message`.
#[pyfunction]
#[pyo3(signature = (path, overrides=None))]
fn load(py: Python<'_>, path: PathBuf, overrides: Option<&Bound<'_, PyAny>>) -> PyResult<Scene> {
    guarded(|| {
        let overrides = match overrides {
            Some(o) => convert::overrides(o)?,
            None => Vec::new(),
        };
        let start = Instant::now();
        let text = std::fs::read_to_string(&path).map_err(|e| {
            scene_error(
                py,
                &lumis_core::error::SceneError::new(&path, format!("cannot read scene file: {e}")),
            )
        })?;
        let description = scene::load::parse_description(&path, &text, &overrides)
            .map_err(|e| scene_error(py, &e))?;
        let parse_time = start.elapsed().as_secs_f64();
        let mut scene = build(py, path.display().to_string(), path, description)?;
        scene.load_time += parse_time;
        Ok(scene)
    })
}

/// Builds a scene from a dict with the fields of the RON format (docs/scene-format.md).
///
/// Structs and maps are dicts, tuples and lists are tuples or lists, plugins are dicts with a
/// "type"; a None value leaves the field out. Relative asset paths are resolved against
/// base_dir (default: the current directory). Raises SceneError (file `<dict>`) or TypeError.
#[pyfunction]
#[pyo3(signature = (scene, base_dir=None))]
fn load_dict(
    py: Python<'_>,
    scene: &Bound<'_, PyDict>,
    base_dir: Option<PathBuf>,
) -> PyResult<Scene> {
    guarded(|| {
        let label = "<dict>";
        let path = base_dir.unwrap_or_default().join(label);
        let value = convert::to_value(scene.as_any(), "scene")?;
        let description: SceneDescription = value.into_rust().map_err(|e| {
            scene_error(
                py,
                &lumis_core::error::SceneError::new(&path, e.to_string()),
            )
        })?;
        build(py, label.to_string(), path, description)
    })
}

/// What a render thread hands back.

#[pymethods]
impl Scene {
    /// Renders the scene; returns a RenderResult with every layer as a float32 numpy array.
    ///
    /// integrator: plugin name (default the scene's; its parameters are kept, as with
    /// `--set integrator.type=NAME`); spp, seed: default the scene's `sampler` values; threads:
    /// default one per core; target_error, time, passes, metric, confidence, max_spp,
    /// max_time, budgets: a render in passes, as `lumis render`'s options of those names;
    /// on_pass: called after each pass with a PassReport, returns False to stop; **params: integrator
    /// parameters (`samples=64`, `aovs=["alpha"]`; None removes one). The GIL is released while
    /// rendering; Ctrl-C stops the render and raises KeyboardInterrupt (the partial image is
    /// discarded). Raises PluginError for an unknown integrator or refused parameters,
    /// ValueError for settings a render in passes refuses, RenderError if the render cannot
    /// run.
    #[pyo3(signature = (
        integrator=None, spp=None, seed=None, threads=None, target_error=None, time=None,
        passes=None, metric=None, confidence=None, max_spp=None, max_time=None, on_pass=None,
        budgets=None, **params
    ))]
    #[allow(clippy::too_many_arguments)]
    fn render(
        &self,
        py: Python<'_>,
        integrator: Option<String>,
        spp: Option<u32>,
        seed: Option<u64>,
        threads: Option<usize>,
        target_error: Option<f64>,
        time: Option<f64>,
        passes: Option<u32>,
        metric: Option<String>,
        confidence: Option<f64>,
        max_spp: Option<u32>,
        max_time: Option<f64>,
        on_pass: Option<Bound<'_, PyAny>>,
        budgets: Option<String>,
        params: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<RenderResult> {
        guarded(|| {
            if spp == Some(0) {
                return Err(PyValueError::new_err("spp must be at least 1"));
            }
            if (target_error.is_some() || time.is_some()) && spp.is_some() {
                return Err(PyValueError::new_err(
                    "spp fixes the samples; a render to target_error or in a time chooses them (cap them with max_spp)",
                ));
            }
            let spp = spp.unwrap_or(self.description.sampler.spp);
            let seed = seed.unwrap_or(self.description.sampler.seed);
            let request = Request {
                target_error,
                time,
                passes,
                replay: None,
                metric: metric
                    .as_deref()
                    .map(Metric::parse)
                    .transpose()
                    .map_err(PyValueError::new_err)?,
                confidence,
                max_spp,
                max_time,
            };
            let settings = request
                .settings(spp, str::to_string)
                .map_err(PyValueError::new_err)?;
            let budgets = budgets
                .as_deref()
                .map(Budgets::parse)
                .transpose()
                .map_err(PyValueError::new_err)?
                .unwrap_or_default();
            if budgets != Budgets::Uniform
                && !settings.as_ref().is_some_and(Settings::estimates_error)
            {
                return Err(PyValueError::new_err(
                    "budgets=\"per-pixel\" needs a render in passes of even sizes (target_error, time, or passes with an even spp of at least twice the passes)",
                ));
            }
            if settings.is_none() && on_pass.is_some() {
                return Err(PyValueError::new_err(
                    "on_pass is called after each pass of a render in passes (target_error, time or passes)",
                ));
            }
            let mut spec = self.description.integrator.clone();
            if let Some(kind) = integrator {
                spec.kind = kind;
            }
            if let Some(params) = params {
                for (key, value) in params.iter() {
                    let key: String = key.extract()?;
                    if value.is_none() {
                        spec.params.remove(&key);
                    } else {
                        let value = convert::to_value(&value, &key)?;
                        spec.params.insert(key, value);
                    }
                }
            }
            let base = self.path.parent().unwrap_or(Path::new("")).to_path_buf();
            let mut integrator = scene::load::build_integrator(&spec, &base)
                .map_err(|e| PluginError::new_err(format!("{}: {e}", self.path.display())))?;

            let built = self.built.clone();
            let Some(settings) = settings else {
                let (film, stats) = beside_python(
                    py,
                    "lumis-render",
                    move |cancel, _| {
                        let mut scene = built.lock().unwrap_or_else(PoisonError::into_inner);
                        scene.spp = spp;
                        scene.seed = seed;
                        integrator.preprocess(&scene);
                        lumis_core::render::render_cancellable(
                            &scene,
                            integrator.as_ref(),
                            threads.unwrap_or(0),
                            &|_| {},
                            cancel,
                        )
                        .map_err(|e| format!("cannot start the render threads: {e}"))
                    },
                    || Ok(()),
                    |_| Ok(true),
                )?
                .map_err(RenderError::new_err)?;
                return RenderResult::new(py, self, film, stats, spec, spp, seed, None);
            };
            let thread_settings = settings.clone();
            let (film, stats, history) = beside_python(
                py,
                "lumis-render",
                move |cancel, report| {
                    let mut scene = built.lock().unwrap_or_else(PoisonError::into_inner);
                    scene.spp = spp;
                    scene.seed = seed;
                    integrator.preprocess(&scene);
                    let settings = thread_settings;
                    let mut state = RenderState::new(&scene, integrator.as_ref(), &settings);
                    let outcome = lumis_core::progressive::run(
                        &scene,
                        integrator.as_mut(),
                        &settings,
                        &mut state,
                        Scope::whole(threads.unwrap_or(0)).with_budgets(budgets),
                        cancel,
                        &|_| {},
                        &mut |state| {
                            if report(PassReport::new(&state.history)) {
                                Control::Continue
                            } else {
                                Control::Stop
                            }
                        },
                    )
                    .map_err(|e| format!("cannot start the render threads: {e}"))?;
                    let film = state.sums.resolve(&scene, integrator.as_ref());
                    Ok::<_, String>((film, outcome.stats, state.history))
                },
                || Ok(()),
                |report| match &on_pass {
                    // Only False stops (a callback that returns nothing goes on).
                    Some(callback) => {
                        let answer = callback.call1((report,))?;
                        Ok(!answer.is(pyo3::types::PyBool::new(py, false).as_any()))
                    }
                    None => Ok(true),
                },
            )?
            .map_err(RenderError::new_err)?;
            RenderResult::new(
                py,
                self,
                film,
                stats,
                spec,
                history.samples(),
                seed,
                Some((settings, history)),
            )
        })
    }

    /// The scene as named when loaded: its path as given, or `<dict>`.
    #[getter]
    fn name(&self) -> &str {
        &self.label
    }

    /// Seconds spent reading, parsing and building the scene.
    #[getter]
    fn load_time(&self) -> f64 {
        self.load_time
    }

    /// Size of the full film, (width, height).
    #[getter]
    fn size(&self) -> (u32, u32) {
        (self.description.film.width, self.description.film.height)
    }

    /// Camera samples per pixel and seed the scene asks for.
    #[getter]
    fn spp(&self) -> u32 {
        self.description.sampler.spp
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.description.sampler.seed
    }

    /// The scene's integrator: {"type": name, parameter: value, ...}.
    #[getter]
    fn integrator<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        plugin_spec_dict(py, &self.description.integrator)
    }

    fn __repr__(&self) -> String {
        let film = &self.description.film;
        format!(
            "<lumis.Scene {} {}x{}, {} spp, integrator {}>",
            self.label,
            film.width,
            film.height,
            self.description.sampler.spp,
            self.description.integrator.kind
        )
    }
}

fn plugin_spec_dict<'py>(py: Python<'py>, spec: &PluginSpec) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("type", &spec.kind)?;
    for (key, value) in &spec.params {
        dict.set_item(key, convert::from_value(py, value)?)?;
    }
    Ok(dict)
}

/// What a render in passes reports after each pass (to `Scene.render`'s `on_pass`, and in
/// `RenderResult.passes`).
#[pyclass(module = "lumis", frozen)]
#[derive(Clone, Debug)]
struct PassReport {
    index: usize,
    samples: u32,
    time: f64,
    error: Option<lumis_core::error_estimate::ErrorEstimate>,
    last: bool,
}

impl PassReport {
    /// The report of the latest pass of `history`.
    fn new(history: &History) -> Self {
        Self::of(history, history.passes.len() - 1)
    }

    /// The report of pass `index` of `history`.
    fn of(history: &History, index: usize) -> Self {
        let record = &history.passes[index];
        let seconds: f64 = history.passes[..=index].iter().map(|p| p.seconds).sum();
        let last = index + 1 == history.passes.len() && history.complete();
        PassReport {
            index,
            samples: record.pass.end,
            time: if index + 1 == history.passes.len() {
                history.elapsed
            } else {
                seconds
            },
            error: record.error,
            last,
        }
    }
}

#[pymethods]
impl PassReport {
    /// The pass's index, 0 for the first.
    #[getter]
    fn index(&self) -> usize {
        self.index
    }

    /// Camera samples per pixel after the pass.
    #[getter]
    fn samples(&self) -> u32 {
        self.samples
    }

    /// Seconds since the render's first pass started.
    #[getter]
    fn time(&self) -> f64 {
        self.time
    }

    /// The image's estimated error after the pass (None if the render estimates none).
    #[getter]
    fn error(&self) -> Option<f64> {
        self.error.map(|e| e.value)
    }

    /// The interval (low, high) that holds the image's error with the render's confidence.
    #[getter]
    fn interval(&self) -> Option<(f64, f64)> {
        self.error.map(|e| (e.low, e.high))
    }

    /// The error's metric, "relmse" or "mse".
    #[getter]
    fn metric(&self) -> Option<&'static str> {
        self.error.map(|e| e.metric.name())
    }

    /// The interval's confidence.
    #[getter]
    fn confidence(&self) -> Option<f64> {
        self.error.map(|e| e.confidence)
    }

    /// Whether this pass was planned as the render's last.
    #[getter]
    fn last(&self) -> bool {
        self.last
    }

    fn __repr__(&self) -> String {
        format!(
            "<lumis.PassReport {}: {} spp, {:.3} s{}{}>",
            self.index,
            self.samples,
            self.time,
            self.error.map_or(String::new(), |e| format!(
                ", error {}",
                render_files::error_text(&e)
            )),
            if self.last { ", the last" } else { "" }
        )
    }
}

/// One output layer: its name, channel names and pixels.
struct Layer {
    name: String,
    channels: Vec<String>,
    pixels: Py<PyArray3<f32>>,
}

/// A finished render: the film as numpy arrays by layer name, its statistics, and the means to
/// write the CLI's files.
#[pyclass(module = "lumis", frozen)]
struct RenderResult {
    film: Film,
    stats: RenderStats,
    metadata: Metadata,
    exposure: f32,
    layers: Vec<Layer>,
    scene: String,
    integrator: PluginSpec,
    spp: u32,
    seed: u64,
    /// A render in passes: what it was asked and its passes.
    passes: Option<(Settings, History)>,
}

/// A read-only (height, width, channels) float32 array from per-pixel interleaved values.
fn array(
    py: Python<'_>,
    height: usize,
    width: usize,
    channels: usize,
    values: Vec<f32>,
) -> PyResult<Py<PyArray3<f32>>> {
    let array = Array3::from_shape_vec((height, width, channels), values)
        .map_err(|e| LumisError::new_err(format!("internal error: layer shape: {e}")))?
        .into_pyarray(py);
    let kwargs = PyDict::new(py);
    kwargs.set_item("write", false)?;
    array.call_method("setflags", (), Some(&kwargs))?;
    Ok(array.unbind())
}

impl RenderResult {
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        scene: &Scene,
        film: Film,
        stats: RenderStats,
        integrator: PluginSpec,
        spp: u32,
        seed: u64,
        passes: Option<(Settings, History)>,
    ) -> PyResult<Self> {
        let (width, height) = (film.window.width as usize, film.window.height as usize);
        let mut layers = vec![Layer {
            name: "color".into(),
            channels: ["R", "G", "B"].map(String::from).to_vec(),
            pixels: array(
                py,
                height,
                width,
                3,
                film.color.iter().flat_map(|c| c.to_array()).collect(),
            )?,
        }];
        for aov in &film.aovs {
            let Some(layer) = film.aov(&aov.name) else {
                continue;
            };
            let channels = layer.channels();
            let values = (0..width * height)
                .flat_map(|i| channels.iter().map(move |c| c[i]))
                .collect();
            layers.push(Layer {
                name: aov.name.clone(),
                channels: aov.channels.clone(),
                pixels: array(py, height, width, channels.len(), values)?,
            });
        }
        let metadata = match &passes {
            Some((settings, history)) => render_files::passes_metadata(
                &scene.label,
                &integrator,
                seed,
                &stats,
                settings,
                history,
            ),
            None => render_files::metadata(&scene.label, &integrator, spp, seed, &stats),
        };
        Ok(RenderResult {
            exposure: scene.description.film.exposure,
            film,
            stats,
            metadata,
            layers,
            scene: scene.label.clone(),
            integrator,
            spp,
            seed,
            passes,
        })
    }

    fn history(&self) -> Option<&History> {
        self.passes.as_ref().map(|(_, history)| history)
    }

    fn layer_names(&self) -> Vec<&str> {
        self.layers.iter().map(|l| l.name.as_str()).collect()
    }
}

#[pymethods]
impl RenderResult {
    fn __getitem__(&self, py: Python<'_>, name: &str) -> PyResult<Py<PyArray3<f32>>> {
        self.layers
            .iter()
            .find(|l| l.name == name)
            .map(|l| l.pixels.clone_ref(py))
            .ok_or_else(|| {
                PyKeyError::new_err(format!(
                    "no layer `{name}`{}; this render has: {}",
                    lumis_core::error::did_you_mean(name, self.layer_names()),
                    self.layer_names().join(", ")
                ))
            })
    }

    fn __contains__(&self, name: &str) -> bool {
        self.layers.iter().any(|l| l.name == name)
    }

    fn __len__(&self) -> usize {
        self.layers.len()
    }

    fn __iter__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        PyList::new(py, self.layer_names())?
            .try_iter()
            .map(Bound::into_any)
    }

    fn keys(&self) -> Vec<&str> {
        self.layer_names()
    }

    /// Every layer by name, colour first: {name: array of shape (height, width, channels)}.
    #[getter]
    fn layers<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for layer in &self.layers {
            dict.set_item(&layer.name, layer.pixels.clone_ref(py))?;
        }
        Ok(dict)
    }

    /// The channel names of every layer: {"color": ["R", "G", "B"], "alpha": ["combined", ...]}.
    #[getter]
    fn channels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let dict = PyDict::new(py);
        for layer in &self.layers {
            dict.set_item(&layer.name, &layer.channels)?;
        }
        Ok(dict)
    }

    /// Render time (wall clock) in seconds, as in the CLI's summary line.
    #[getter]
    fn time(&self) -> f64 {
        self.stats.wall_time.as_secs_f64()
    }

    #[getter]
    fn camera_samples(&self) -> u64 {
        self.stats.camera_samples
    }

    #[getter]
    fn rays(&self) -> u64 {
        self.stats.rays
    }

    #[getter]
    fn threads(&self) -> usize {
        self.stats.threads
    }

    #[getter]
    fn pixels(&self) -> u64 {
        self.stats.pixels_total
    }

    #[getter]
    fn tiles(&self) -> u32 {
        self.stats.tiles_total
    }

    #[getter]
    fn samples_per_second(&self) -> f64 {
        self.stats.camera_samples as f64 / self.stats.wall_time.as_secs_f64()
    }

    #[getter]
    fn rays_per_second(&self) -> f64 {
        self.stats.rays as f64 / self.stats.wall_time.as_secs_f64()
    }

    #[getter]
    fn spp(&self) -> u32 {
        self.spp
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.seed
    }

    /// A render in passes: each pass's report, in order (empty for a plain render).
    #[getter]
    fn passes(&self) -> Vec<PassReport> {
        self.passes.as_ref().map_or(Vec::new(), |(_, history)| {
            (0..history.passes.len())
                .map(|k| PassReport::of(history, k))
                .collect()
        })
    }

    /// The image's estimated error (a render in passes that estimates it; else None).
    #[getter]
    fn error(&self) -> Option<f64> {
        self.history().and_then(History::error).map(|e| e.value)
    }

    /// The interval (low, high) that holds the image's error with the render's confidence.
    #[getter]
    fn error_interval(&self) -> Option<(f64, f64)> {
        self.history()
            .and_then(History::error)
            .map(|e| (e.low, e.high))
    }

    /// Why a render in passes ended: "target", "max-spp", "max-time", "time", "samples",
    /// "replay"; None for a plain render or one stopped by `on_pass`.
    #[getter]
    fn stopped(&self) -> Option<&'static str> {
        self.history()
            .and_then(|h| h.stopped)
            .map(lumis_core::passes::Stop::name)
    }

    /// Whether the image is partial: a render in passes stopped by `on_pass` before the pass
    /// planned as its last (its passes' weights then made to sum to one: consistent, not
    /// unbiased).
    #[getter]
    fn partial(&self) -> bool {
        self.stats.partial() || self.history().is_some_and(|h| !h.complete())
    }

    /// The integrator that rendered: {"type": name, parameter: value, ...}.
    #[getter]
    fn integrator<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        plugin_spec_dict(py, &self.integrator)
    }

    /// The `lumis` metadata of the EXR header, {key: value}.
    #[getter]
    fn metadata(&self) -> Vec<(String, String)> {
        self.metadata.clone()
    }

    /// Writes the EXR, its PNG preview and the AOV previews exactly as `lumis render -o path`.
    #[pyo3(signature = (path, exposure=None))]
    fn write(&self, py: Python<'_>, path: PathBuf, exposure: Option<f32>) -> PyResult<Vec<String>> {
        guarded(|| {
            let exposure = exposure.unwrap_or(self.exposure);
            if !exposure.is_finite() {
                return Err(PyValueError::new_err("exposure must be finite"));
            }
            let written = py
                .detach(|| render_files::write(&self.film, &path, exposure, &self.metadata))
                .map_err(|e| output_error(py, &e))?;
            Ok(written
                .all()
                .iter()
                .map(|p| p.display().to_string())
                .collect())
        })
    }

    fn __repr__(&self) -> String {
        let window = self.film.window;
        format!(
            "<lumis.RenderResult {} ({}x{}, {} spp, {}, {} threads): rendered in {:.3} s, {:.3} M samples/s, {:.2} M rays/s; layers {}>",
            self.scene,
            window.width,
            window.height,
            self.spp,
            self.integrator.kind,
            self.stats.threads,
            self.time(),
            self.samples_per_second() / 1e6,
            self.rays_per_second() / 1e6,
            self.layer_names().join(", ")
        )
    }
}

fn param_dict<'py>(py: Python<'py>, spec: &ParamSpec) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("name", spec.name)?;
    dict.set_item("type", spec.type_name())?;
    dict.set_item("default", spec.default_text())?;
    dict.set_item("valid", spec.range_text())?;
    dict.set_item("unit", spec.unit)?;
    dict.set_item("description", spec.description)?;
    Ok(dict)
}

fn plugins_of<'py, P: PluginInfo + lumis_core::inventory::Collect>(
    py: Python<'py>,
    list: &Bound<'py, PyList>,
) -> PyResult<()> {
    for plugin in registry::plugins::<P>() {
        let dict = PyDict::new(py);
        dict.set_item("kind", P::KIND)?;
        dict.set_item("name", plugin.name())?;
        dict.set_item("description", plugin.description())?;
        let params = PyList::empty(py);
        for spec in plugin.params() {
            params.append(param_dict(py, spec)?)?;
        }
        dict.set_item("parameters", params)?;
        list.append(dict)?;
    }
    Ok(())
}

/// Every registered plugin (BSDFs, emitters, textures, integrators) with its parameters.
#[pyfunction]
fn plugins(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    guarded(|| {
        let list = PyList::empty(py);
        plugins_of::<BsdfPlugin>(py, &list)?;
        plugins_of::<EmitterPlugin>(py, &list)?;
        plugins_of::<TexturePlugin>(py, &list)?;
        plugins_of::<IntegratorPlugin>(py, &list)?;
        Ok(list)
    })
}

#[pymodule]
fn _lumis(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // Keep every built-in plugin crate (and so its registrations) in the extension.
    lumis_bsdfs::link();
    lumis_emitters::link();
    lumis_integrators::link();
    lumis::textures::link();
    let py = m.py();
    m.add("LumisError", py.get_type::<LumisError>())?;
    m.add("SceneError", py.get_type::<SceneError>())?;
    m.add("PluginError", py.get_type::<PluginError>())?;
    m.add("RenderError", py.get_type::<RenderError>())?;
    m.add("OutputError", py.get_type::<OutputError>())?;
    m.add_class::<Scene>()?;
    m.add_class::<RenderResult>()?;
    m.add_class::<PassReport>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(load_dict, m)?)?;
    m.add_function(wrap_pyfunction!(plugins, m)?)?;
    m.add_function(wrap_pyfunction!(study::study, m)?)?;
    Ok(())
}
