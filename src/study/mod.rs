//! `lumis study`: measures the speed/accuracy trade of integrators on scenes, as the paper's
//! Tables 1 and 2 and Figures 2, 3, 4, 7, 8, 10 and 11 do.
//!
//! For each scene and integrator, K independent runs (seeds `seed + 1` … `seed + K`) give the mean
//! sampling variance V[L_{1,α}] (the integrators' `sampling_variance` AOV averaged over pixels),
//! the estimator variance V[L_{N,α}] (each pixel's variance across the runs, averaged), the
//! relative MSE and the mean Lab ΔE*ab against a reference, the median wall time and CPU time,
//! and the efficiency 1 / (V[L_{N,α}] × CPU time). With `equal_time`, every integrator is run
//! again with the N that matches the `alpha` integrator's CPU time. Sweeps vary α's clamping interval
//! (Figure 2), its pilot count M (Figure 7) and N for a fixed M (Figures 3 and 4).
//!
//! Results are written as each row finishes (`results.csv`, `sweeps.csv`, `results.md`), plots
//! and image panels as each scene finishes: an interrupted study keeps everything it finished.

pub mod metrics;
mod panel;
pub mod paper;
mod plots;
mod report;

use anyhow::{Context, Result, bail};
use indicatif::ProgressBar;
use lumis_core::film::Film;
use lumis_core::image_io::{self, Metadata};
use lumis_core::integrator::Integrator;
use lumis_core::math::Rgb;
use lumis_core::scene::Scene;
use lumis_core::scene::description::PluginSpec;
use lumis_core::scene::load::{LoadedScene, build_integrator, load_scene};
use lumis_integrators::{alpha, aovs, balance, mis};
use metrics::RunStatistics;
pub use report::{Row, SweepPoint};
use ron::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

/// An integrator of a study: a plugin with parameters, written `NAME[:key=value]...`
/// (e.g. `alpha:mode=preprocessed:alpha_samples=1024`); the text is its label.
#[derive(Clone, Debug)]
pub struct Choice {
    pub label: String,
    pub spec: PluginSpec,
}

impl Choice {
    pub fn parse(text: &str) -> Result<Self> {
        let mut parts = text.split(':');
        let kind = parts.next().unwrap_or_default().trim();
        if kind.is_empty() {
            bail!("`{text}`: an integrator is written NAME[:key=value]...");
        }
        let mut params = BTreeMap::new();
        for part in parts {
            let Some((key, value)) = part.split_once('=') else {
                bail!("`{text}`: `{part}` is not key=value");
            };
            // Values are RON; a bare word is a string (mode=preprocessed).
            let value = match ron::from_str::<Value>(value) {
                Ok(Value::Unit) | Err(_) => Value::String(value.to_string()),
                Ok(v) => v,
            };
            params.insert(key.trim().to_string(), value);
        }
        for reserved in [mis::SAMPLES, mis::AOVS] {
            if params.contains_key(reserved) {
                bail!("`{text}`: `{reserved}` is set by the study, not per integrator");
            }
        }
        Ok(Self {
            label: text.to_string(),
            spec: PluginSpec {
                kind: kind.to_string(),
                params,
            },
        })
    }

    /// The `mode` parameter, if set (the `alpha` integrator's integrated / preprocessed / fixed).
    pub fn mode(&self) -> Option<&str> {
        match self.spec.params.get(alpha::MODE) {
            Some(Value::String(s)) => Some(s),
            _ => None,
        }
    }

    /// The second-order α with integrated estimation (the paper's Table 2 method).
    pub fn is_integrated_alpha(&self) -> bool {
        self.spec.kind == alpha::NAME && matches!(self.mode(), None | Some(alpha::INTEGRATED))
    }

    fn with(&self, samples: u32, extra: &[(&str, Value)], aovs: &[&str]) -> PluginSpec {
        let mut spec = self.spec.clone();
        spec.params.insert(
            mis::SAMPLES.into(),
            Value::Number(u64::from(samples).into()),
        );
        let aovs = aovs.iter().map(|a| Value::String(a.to_string())).collect();
        spec.params.insert(mis::AOVS.into(), Value::Seq(aovs));
        for (k, v) in extra {
            spec.params.insert(k.to_string(), v.clone());
        }
        spec
    }
}

/// The default integrator list: every member of the MIS family, α both ways.
pub const DEFAULT_INTEGRATORS: &str =
    "bsdf,light,balance,power,max,alpha,alpha:mode=preprocessed:alpha_samples=256";

/// Where the reference image comes from.
#[derive(Clone, Debug)]
pub enum ReferenceSource {
    /// An EXR given by the user (one scene only).
    File(PathBuf),
    /// Rendered with the balance heuristic at this many samples per light per pixel, cached
    /// next to the scene.
    Samples(u32),
}

/// Which sweeps to run.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sweeps {
    /// α's clamping interval (Figure 2).
    pub clamp: bool,
    /// α's pilot count M (Figure 7).
    pub alpha_samples: bool,
    /// N for a fixed M (Figures 3 and 4).
    pub convergence: bool,
}

impl Sweeps {
    pub fn parse(list: &str) -> Result<Self> {
        let mut sweeps = Self::default();
        for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match item {
                "clamp" => sweeps.clamp = true,
                "m" => sweeps.alpha_samples = true,
                "n" => sweeps.convergence = true,
                "all" => {
                    sweeps = Self {
                        clamp: true,
                        alpha_samples: true,
                        convergence: true,
                    }
                }
                "none" => sweeps = Self::default(),
                other => bail!("unknown sweep `{other}`: the sweeps are clamp, m, n, all, none"),
            }
        }
        Ok(sweeps)
    }

    fn any(&self) -> bool {
        self.clamp || self.alpha_samples || self.convergence
    }
}

/// Everything a study is asked to do.
#[derive(Clone, Debug)]
pub struct StudyConfig {
    pub scenes: Vec<PathBuf>,
    pub integrators: Vec<Choice>,
    /// N, samples per light per camera sample.
    pub samples: u32,
    /// K, independent runs per configuration (at least 2: V[L_N] is measured across runs).
    pub runs: u32,
    pub reference: ReferenceSource,
    pub equal_time: bool,
    pub sweeps: Sweeps,
    /// `--set` overrides applied to every scene (e.g. a smaller film).
    pub overrides: Vec<String>,
    pub threads: usize,
    pub seed: u64,
    pub out: PathBuf,
    /// The Markdown report (default `out/results.md`); its links are relative to its directory.
    pub report: Option<PathBuf>,
    /// Markdown written by hand (a reading of the results) inserted after the summary.
    pub notes: Option<PathBuf>,
    /// The command line that ran the study, quoted in the report so that it can be run again.
    pub command: Option<String>,
}

impl StudyConfig {
    pub fn report_path(&self) -> PathBuf {
        self.report
            .clone()
            .unwrap_or_else(|| self.out.join("results.md"))
    }
}

/// The study was interrupted; what it finished is written.
#[derive(Debug, thiserror::Error)]
#[error("interrupted: the finished rows are in {0}")]
pub struct Interrupted(pub PathBuf);

/// Clamping interval sizes of the Figure 2 sweep (0 = balance heuristic, 1 = no clamping).
const CLAMP_SIZES: [f64; 8] = [0.0, 0.2, 0.4, 0.6, 0.8, 0.9, 0.95, 1.0];
/// M as fractions of N in the Figure 7 sweep.
const ALPHA_SAMPLE_FRACTIONS: [f64; 6] = [1.0 / 32.0, 1.0 / 16.0, 0.125, 0.25, 0.5, 0.75];
/// N as multiples of M in the Figures 3 and 4 sweep.
const CONVERGENCE_MULTIPLES: [u32; 4] = [1, 2, 4, 8];
/// Independent runs whose mean is a rendered reference: their spread gives each reference pixel's
/// own variance (the AOV's V[L₁] would not: it is the mixture's, which can be far larger than
/// the variance of the stratified estimator).
const REFERENCE_RUNS: u32 = 16;

/// What K runs of one configuration measured.
struct Measurement {
    samples: u32,
    runs: RunStatistics,
    sampling_variance: f64,
    sampling_variance_median: f64,
    rel_mse: f64,
    lab_error: f64,
    time: f64,
    cpu_time: f64,
    /// The first run's image and α map (for the panels).
    image: Vec<Rgb>,
    alpha_map: Option<Vec<[f32; 3]>>,
}

/// The reference image of a scene and the variance of its pixels' estimates (when known).
pub struct Reference {
    pub pixels: Vec<Rgb>,
    pub pixel_variance: Option<Vec<f64>>,
    pub samples: Option<u32>,
    pub time: Option<f64>,
    pub path: PathBuf,
    pub cached: bool,
}

impl Reference {
    /// Standard error of the reference's mean luminance (0 if unknown).
    fn mean_standard_error(&self) -> f64 {
        self.pixel_variance.as_ref().map_or(0.0, |v| {
            let p = v.len().max(1) as f64;
            (v.iter().sum::<f64>() / (p * p)).sqrt()
        })
    }

    /// The reference's own estimator variance, averaged over pixels.
    pub fn variance(&self) -> Option<f64> {
        self.pixel_variance
            .as_ref()
            .map(|v| v.iter().sum::<f64>() / v.len().max(1) as f64)
    }
}

/// One scene's results, for the report and the plots.
pub struct SceneResults {
    pub path: PathBuf,
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub reference: Reference,
    pub rows: Vec<Row>,
    pub sweeps: Vec<SweepPoint>,
}

/// Runs a study, reporting progress on `bar` and stopping at the next camera sample once `cancel` is set.
pub fn run(config: &StudyConfig, bar: &ProgressBar, cancel: &AtomicBool) -> Result<()> {
    validate(config)?;
    if let Some(notes) = &config.notes {
        std::fs::read_to_string(notes)
            .with_context(|| format!("cannot read --notes `{}`", notes.display()))?;
    }
    plots::register_font()?;
    std::fs::create_dir_all(&config.out)
        .with_context(|| format!("cannot create `{}`", config.out.display()))?;
    bar.set_length(planned_renders(config));
    let mut study = Study {
        config,
        bar,
        cancel,
        finished: Vec::new(),
    };
    for path in &config.scenes {
        study.scene(path)?;
    }
    bar.finish_and_clear();
    Ok(())
}

fn validate(config: &StudyConfig) -> Result<()> {
    if config.runs < 2 {
        bail!("--runs must be at least 2: the estimator variance is measured across runs");
    }
    if config.integrators.is_empty() {
        bail!("--integrators is empty");
    }
    if let ReferenceSource::File(file) = &config.reference
        && config.scenes.len() != 1
    {
        bail!(
            "--reference `{}` is one image: give exactly one scene with it",
            file.display()
        );
    }
    let has_alpha = config.integrators.iter().any(Choice::is_integrated_alpha);
    if config.equal_time && !has_alpha {
        bail!(
            "--equal-time matches every integrator's time to `alpha`'s: add `alpha` to --integrators"
        );
    }
    for choice in &config.integrators {
        lumis_core::registry::find::<lumis_core::registry::IntegratorPlugin>(&choice.spec.kind)
            .map_err(|e| anyhow::anyhow!("--integrators: {e}"))?;
    }
    Ok(())
}

/// The number of renders a study will make (for the progress bar).
fn planned_renders(config: &StudyConfig) -> u64 {
    let k = config.runs as u64;
    let n = config.integrators.len() as u64;
    let mut per_scene = 1 + n * k;
    if config.equal_time {
        per_scene += (n - 1) * k;
    }
    if config.sweeps.clamp {
        per_scene += CLAMP_SIZES.len() as u64 * k;
    }
    if config.sweeps.alpha_samples {
        per_scene += ALPHA_SAMPLE_FRACTIONS.len() as u64 * k;
    }
    if config.sweeps.convergence {
        per_scene += 2 * CONVERGENCE_MULTIPLES.len() as u64 * k;
    }
    per_scene * config.scenes.len() as u64
}

struct Study<'a> {
    config: &'a StudyConfig,
    bar: &'a ProgressBar,
    cancel: &'a AtomicBool,
    finished: Vec<SceneResults>,
}

impl Study<'_> {
    fn scene(&mut self, path: &Path) -> Result<()> {
        let config = self.config;
        let name = path.file_stem().map_or_else(
            || path.display().to_string(),
            |s| s.to_string_lossy().into(),
        );
        self.bar.set_message(format!("{name}: loading"));
        let mut loaded = load_scene(path, &config.overrides)?;
        // Rays through pixel centres: runs then differ only in the light and BSDF samples that
        // MIS is about, not in where the pixel is shaded (antialiasing noise no strategy changes).
        loaded.scene.jitter = false;
        let base = path.parent().unwrap_or(Path::new("")).to_path_buf();
        let reference = self.reference(path, &name, &mut loaded, &base)?;
        self.finished.push(SceneResults {
            path: path.to_path_buf(),
            name: name.clone(),
            width: loaded.scene.window.width,
            height: loaded.scene.window.height,
            reference,
            rows: Vec::new(),
            sweeps: Vec::new(),
        });

        // Equal samples.
        let mut images = panel::PanelImages::default();
        let mut times = Vec::new();
        for choice in &config.integrators {
            let m = self.measure(&name, &mut loaded, &base, choice, config.samples, &[], true)?;
            times.push(m.cpu_time);
            images.keep(choice, &m, false);
            self.add_row(choice, "equal samples", &m)?;
        }
        // Equal time: N scaled by the ratio of CPU times (close to linear in N). CPU time, not
        // wall time, so that other programs running on the machine do not skew the match.
        if config.equal_time {
            let alpha = config
                .integrators
                .iter()
                .position(Choice::is_integrated_alpha)
                .context("no alpha integrator")?;
            for (i, choice) in config.integrators.iter().enumerate() {
                if i == alpha {
                    let row = self.current().rows[alpha].clone();
                    self.push_row(Row {
                        budget: "equal time".into(),
                        ..row
                    })?;
                    continue;
                }
                // Its pilot alone (M samples at α = ½) outlasts α's whole render.
                if choice.mode() == Some(alpha::PREPROCESSED) {
                    self.bar.inc(config.runs as u64);
                    continue;
                }
                let ratio = times[alpha] / times[i].max(1e-9);
                let n = ((config.samples as f64 * ratio).round() as u32).clamp(2, 1 << 20);
                let m = self.measure(&name, &mut loaded, &base, choice, n, &[], true)?;
                images.keep(choice, &m, true);
                self.add_row(choice, "equal time", &m)?;
            }
        }
        if config.sweeps.any() {
            self.sweeps(&name, &mut loaded, &base)?;
        }

        let results = self.current();
        panel::write(&config.out, results, &images, loaded.scene.exposure)?;
        plots::scene_plots(&config.out, results)?;
        plots::study_plots(&config.out, &self.finished)?;
        report::write_markdown(config, &self.finished)?;
        Ok(())
    }

    fn current(&self) -> &SceneResults {
        self.finished.last().expect("a scene is being studied")
    }

    fn add_row(&mut self, choice: &Choice, budget: &str, m: &Measurement) -> Result<()> {
        let results = self.current();
        let reference = &results.reference;
        let mean = m.runs.mean();
        let ref_mean = metrics::mean_luminance(&reference.pixels);
        // Pixels are independent estimates: the image mean's variance is the sum of the pixels'
        // (from the spread of the K runs) over P², plus the reference's own.
        let sigma = m
            .runs
            .mean_standard_error()
            .hypot(reference.mean_standard_error());
        let estimator_variance = m.runs.estimator_variance();
        let row = Row {
            scene: results.name.clone(),
            integrator: choice.label.clone(),
            kind: choice.spec.kind.clone(),
            mode: choice.mode().unwrap_or_default().to_string(),
            budget: budget.into(),
            samples: m.samples,
            runs: m.runs.runs(),
            width: results.width,
            height: results.height,
            sampling_variance: m.sampling_variance,
            sampling_variance_median: m.sampling_variance_median,
            estimator_variance,
            rel_mse: m.rel_mse,
            lab_error: m.lab_error,
            time: m.time,
            cpu_time: m.cpu_time,
            efficiency: 1.0 / (estimator_variance * m.cpu_time),
            mean,
            mean_sigma: sigma,
            reference_mean: ref_mean,
            z: (mean - ref_mean) / sigma,
        };
        self.push_row(row)
    }

    fn push_row(&mut self, row: Row) -> Result<()> {
        self.finished
            .last_mut()
            .expect("a scene is being studied")
            .rows
            .push(row);
        report::write_csv(&self.config.out, &self.finished)?;
        report::write_markdown(self.config, &self.finished)
    }

    fn push_sweep(&mut self, point: SweepPoint) -> Result<()> {
        self.finished
            .last_mut()
            .expect("a scene is being studied")
            .sweeps
            .push(point);
        report::write_sweeps_csv(&self.config.out, &self.finished)
    }

    fn sweeps(&mut self, name: &str, loaded: &mut LoadedScene, base: &Path) -> Result<()> {
        let config = self.config;
        let n = config.samples;
        let alpha = Choice::parse(alpha::NAME)?;
        let number = |v: f64| Value::Number(v.into());
        let interval = |lo: f64, hi: f64| Value::Seq(vec![number(lo), number(hi)]);
        if config.sweeps.clamp {
            for size in CLAMP_SIZES {
                let clamp = interval(0.5 - size / 2.0, 0.5 + size / 2.0);
                let m = self.measure(
                    name,
                    loaded,
                    base,
                    &alpha,
                    n,
                    &[(alpha::CLAMP, clamp)],
                    false,
                )?;
                self.push_sweep(SweepPoint::new(name, "clamp", alpha::NAME, size, &m))?;
            }
        }
        if config.sweeps.alpha_samples {
            let mut counts: Vec<u32> = ALPHA_SAMPLE_FRACTIONS
                .iter()
                .map(|f| ((n as f64 * f).round() as u32).max(2))
                .filter(|&m| m < n)
                .collect();
            counts.dedup();
            for count in counts {
                let extra = [(alpha::ALPHA_SAMPLES, Value::Number(u64::from(count).into()))];
                let m = self.measure(name, loaded, base, &alpha, n, &extra, false)?;
                self.push_sweep(SweepPoint::new(name, "m", alpha::NAME, count as f64, &m))?;
            }
        }
        if config.sweeps.convergence {
            let fixed_m = (n / 4).max(1);
            let balance = Choice::parse(balance::NAME)?;
            for multiple in CONVERGENCE_MULTIPLES {
                let samples = fixed_m * multiple;
                let extra = [(
                    alpha::ALPHA_SAMPLES,
                    Value::Number(u64::from(fixed_m).into()),
                )];
                let m = self.measure(name, loaded, base, &alpha, samples, &extra, false)?;
                self.push_sweep(SweepPoint::new(name, "n", alpha::NAME, samples as f64, &m))?;
                let m = self.measure(name, loaded, base, &balance, samples, &[], false)?;
                self.push_sweep(SweepPoint::new(
                    name,
                    "n",
                    balance::NAME,
                    samples as f64,
                    &m,
                ))?;
            }
        }
        Ok(())
    }

    /// K runs of one integrator configuration.
    #[allow(clippy::too_many_arguments)]
    fn measure(
        &self,
        name: &str,
        loaded: &mut LoadedScene,
        base: &Path,
        choice: &Choice,
        samples: u32,
        extra: &[(&str, Value)],
        against_reference: bool,
    ) -> Result<Measurement> {
        let config = self.config;
        let mut aovs = vec![aovs::SAMPLING_VARIANCE];
        if choice.spec.kind == alpha::NAME {
            aovs.push(aovs::ALPHA);
        }
        let spec = choice.with(samples, extra, &aovs);
        let mut integrator = build_integrator(&spec, base)
            .map_err(anyhow::Error::msg)
            .with_context(|| format!("--integrators `{}`", choice.label))?;
        let reference = &self.current().reference;
        let pixels = (loaded.scene.window.width * loaded.scene.window.height) as usize;
        let mut runs = RunStatistics::new(pixels);
        let (mut sampling, mut medians, mut rel_mse, mut lab) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        let (mut times, mut cpu_times) = (Vec::new(), Vec::new());
        let mut image = Vec::new();
        let mut alpha_map = None;
        let exposure = loaded.scene.exposure.exp2();
        let what = extra
            .iter()
            .map(|(k, v)| format!(" {k}={}", ron::to_string(v).unwrap_or_default()))
            .collect::<String>();
        for k in 0..config.runs {
            self.bar.set_message(format!(
                "{name}: {} N={samples}{what} run {}/{}",
                choice.label,
                k + 1,
                config.runs
            ));
            loaded.scene.seed = config.seed + 1 + k as u64;
            let (film, time, cpu_time) = self.render(&loaded.scene, integrator.as_mut())?;
            runs.add(&film.color);
            let variance = aov(&film, aovs::SAMPLING_VARIANCE, aovs::Y)
                .context("the integrator has no sampling_variance AOV")?;
            sampling.push(variance.iter().map(|&v| v as f64).sum::<f64>() / pixels as f64);
            medians.push(metrics::median(
                &mut variance.iter().map(|&v| v as f64).collect::<Vec<_>>(),
            ));
            if against_reference {
                rel_mse.push(metrics::relative_mse(&film.color, &reference.pixels));
                let delta = metrics::lab_difference(&film.color, &reference.pixels, exposure);
                lab.push(delta.iter().sum::<f64>() / pixels as f64);
            }
            times.push(time);
            cpu_times.push(cpu_time);
            if k == 0 {
                alpha_map = alpha_colors(&film);
                image = film.color;
            }
            self.bar.inc(1);
        }
        let mean = |v: &[f64]| {
            if v.is_empty() {
                f64::NAN
            } else {
                v.iter().sum::<f64>() / v.len() as f64
            }
        };
        Ok(Measurement {
            samples,
            sampling_variance: mean(&sampling),
            sampling_variance_median: mean(&medians),
            rel_mse: mean(&rel_mse),
            lab_error: mean(&lab),
            time: metrics::median(&mut times),
            cpu_time: metrics::median(&mut cpu_times),
            runs,
            image,
            alpha_map,
        })
    }

    /// Renders, failing with [`Interrupted`] if the user stopped the study; also returns the
    /// wall time and the CPU time of the render.
    fn render(&self, scene: &Scene, integrator: &mut dyn Integrator) -> Result<(Film, f64, f64)> {
        let cpu_start = process_cpu_time();
        integrator.preprocess(scene);
        let (film, stats) = lumis_core::render::render_cancellable(
            scene,
            &*integrator,
            self.config.threads,
            &|_| {},
            self.cancel,
        )
        .context("cannot start the render threads")?;
        if stats.partial() {
            return Err(Interrupted(self.config.out.clone()).into());
        }
        let wall = stats.wall_time.as_secs_f64();
        let cpu = process_cpu_time() - cpu_start;
        Ok((film, wall, if cpu.is_finite() { cpu } else { wall }))
    }

    /// The scene's reference: the user's file, a cached render with the same parameters, or a
    /// new balance-heuristic render cached next to the scene.
    fn reference(
        &self,
        path: &Path,
        name: &str,
        loaded: &mut LoadedScene,
        base: &Path,
    ) -> Result<Reference> {
        let window = loaded.scene.window;
        let pixels = (window.width * window.height) as usize;
        let samples = match &self.config.reference {
            ReferenceSource::File(file) => {
                self.bar.inc(1);
                return read_reference(file, pixels, None, false);
            }
            ReferenceSource::Samples(s) => *s,
        };
        let per_run = samples.div_ceil(REFERENCE_RUNS).max(2);
        let total = per_run * REFERENCE_RUNS;
        let file = path.with_file_name(format!(
            "{name}.reference-{}x{}-{total}.exr",
            window.width, window.height
        ));
        let key = reference_key(path, &self.config.overrides, total)?;
        if let Ok(metadata) = image_io::read_exr_metadata(&file)
            && metadata.iter().any(|(k, v)| k == "key" && *v == key)
        {
            self.bar.inc(1);
            return read_reference(&file, pixels, Some(total), true);
        }

        self.bar.set_message(format!(
            "{name}: reference, {total} samples per light per pixel (balance)"
        ));
        let spec = Choice::parse(balance::NAME)?.with(per_run, &[], &[]);
        let mut integrator = build_integrator(&spec, base).map_err(anyhow::Error::msg)?;
        let spp = std::mem::replace(&mut loaded.scene.spp, 1);
        let mut sum = vec![glam::DVec3::ZERO; pixels];
        let mut runs = RunStatistics::new(pixels);
        let mut time = 0.0;
        for k in 0..REFERENCE_RUNS {
            loaded.scene.seed = self.config.seed + 1_000_003 + k as u64;
            let rendered = self.render(&loaded.scene, integrator.as_mut());
            let (film, wall, _) = match rendered {
                Ok(r) => r,
                Err(e) => {
                    loaded.scene.spp = spp;
                    return Err(e);
                }
            };
            time += wall;
            runs.add(&film.color);
            for (s, c) in sum.iter_mut().zip(&film.color) {
                *s += c.as_dvec3();
            }
        }
        loaded.scene.spp = spp;
        let scene = &loaded.scene;
        let aov = lumis_core::output::Aov {
            name: "reference_variance".into(),
            channels: vec!["Y".into()],
            preview: false,
        };
        let mut film = Film::new(scene.width, scene.height, window, vec![aov]);
        let n = REFERENCE_RUNS as f64;
        film.color = sum.iter().map(|s| (*s / n).as_vec3()).collect();
        film.aov_data = runs.pixel_variances().map(|v| (v / n) as f32).collect();
        let metadata: Metadata = vec![
            ("scene".into(), path.display().to_string()),
            ("key".into(), key),
            ("integrator".into(), balance::NAME.into()),
            ("samples".into(), total.to_string()),
            ("time".into(), format!("{time:.3}")),
        ];
        image_io::write_exr(&film, &file, &metadata)?;
        self.bar.inc(1);
        let mut reference = read_reference(&file, pixels, Some(total), false)?;
        reference.time = Some(time);
        Ok(reference)
    }
}

/// CPU seconds used by this process so far (all threads), or NaN where it cannot be read.
fn process_cpu_time() -> f64 {
    #[cfg(unix)]
    {
        let mut t = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes one timespec through a valid pointer.
        if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) } == 0 {
            return t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9;
        }
    }
    f64::NAN
}

/// Identifies what a cached reference was made from: the scene text, the overrides, the
/// sample count and the program version.
fn reference_key(path: &Path, overrides: &[String], samples: u32) -> Result<String> {
    use std::hash::{Hash, Hasher};
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read `{}`", path.display()))?;
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    // "runs": the format of a reference made of independent runs (older caches are stale).
    let format = "runs";
    (text, overrides, samples, env!("CARGO_PKG_VERSION"), format).hash(&mut hasher);
    Ok(format!("{:016x}", hasher.finish()))
}

fn read_reference(
    file: &Path,
    pixels: usize,
    samples: Option<u32>,
    cached: bool,
) -> Result<Reference> {
    let channels = image_io::read_exr_channels(file).map_err(anyhow::Error::msg)?;
    let channel = |name: &str| channels.iter().find(|(n, _)| n == name).map(|(_, v)| v);
    let (Some(r), Some(g), Some(b)) = (channel("R"), channel("G"), channel("B")) else {
        bail!("reference `{}` has no R, G, B channels", file.display());
    };
    if r.len() != pixels {
        bail!(
            "reference `{}` has {} pixels, the scene renders {pixels}",
            file.display(),
            r.len()
        );
    }
    // The variance of each reference pixel, as a rendered reference stores it.
    let pixel_variance =
        channel("reference_variance.Y").map(|v| v.iter().map(|&v| v as f64).collect());
    let time = image_io::read_exr_metadata(file)
        .ok()
        .and_then(|m| m.into_iter().find(|(k, _)| k == "time"))
        .and_then(|(_, v)| v.parse().ok());
    Ok(Reference {
        pixels: (0..pixels).map(|i| Rgb::new(r[i], g[i], b[i])).collect(),
        pixel_variance,
        samples,
        time,
        path: file.to_path_buf(),
        cached,
    })
}

fn aov(film: &Film, name: &str, channel: &str) -> Option<Vec<f32>> {
    film.aov(name)?.channel(channel)
}

fn alpha_colors(film: &Film) -> Option<Vec<[f32; 3]>> {
    let [r, g, b] = ["R", "G", "B"].map(|c| aov(film, aovs::ALPHA_COLOR, c));
    let (r, g, b) = (r?, g?, b?);
    Some((0..r.len()).map(|i| [r[i], g[i], b[i]]).collect())
}
