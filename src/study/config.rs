//! What a study is asked to do: the scenes, the integrator configurations (`NAME[:key=value]...`),
//! the ladder of budgets, the runs and the rule that grows them, the reference, the sweeps, and
//! where the outputs go. Parsed from the command line by `src/main.rs`, checked by
//! [`StudyConfig::validate`] before anything is rendered.

use anyhow::{Context, Result, bail};
use lumis_core::budgets::Budgets;
use lumis_core::params::ParamKind;
use lumis_core::registry::{IntegratorPlugin, find};
use lumis_core::scene::description::PluginSpec;
use lumis_integrators::{alpha, aovs, mis, path};
use ron::Value;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// An integrator of a study: a plugin with parameters, written `NAME[:key=value]...`
/// (e.g. `alpha:mode=preprocessed:alpha_samples=1024`); the text is its label. The study sets
/// `aovs` itself, and the budget: `samples` of a direct integrator; of a `path` row the camera
/// samples per pixel, its `samples` (N per light at the first vertex) being the row's. Two keys are the study's, not the plugin's:
/// `passes=K` renders in K passes of 2 camera samples each ([`InPasses`]), and with it
/// `budgets=per-pixel` spreads each pass's samples over the pixels (docs/integrators.md).
#[derive(Clone, Debug, PartialEq)]
pub struct Choice {
    pub label: String,
    pub spec: PluginSpec,
    pub in_passes: Option<InPasses>,
}

/// A configuration rendered in passes: `passes` passes of [`CAMERA_SAMPLES_PER_PASS`] camera
/// samples, spread over the pixels by `budgets`. Its budget B is total work, camera samples ×
/// N: N = B / (2 · passes) samples per light (at least 1).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InPasses {
    pub passes: u32,
    pub budgets: Budgets,
}

/// Camera samples per pixel of each pass of a configuration rendered in passes: the fewest
/// that keep the half-images per-pixel budgets read.
pub const CAMERA_SAMPLES_PER_PASS: u32 = 2;

/// The study's keys of a choice.
pub const PASSES: &str = "passes";
pub const BUDGETS: &str = "budgets";

impl InPasses {
    /// Camera samples per pixel of the render.
    pub fn spp(&self) -> u32 {
        self.passes * CAMERA_SAMPLES_PER_PASS
    }
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
            let budgeted_by_spp = kind == path::NAME && reserved == mis::SAMPLES;
            if params.contains_key(reserved) && !budgeted_by_spp {
                bail!("`{text}`: `{reserved}` is set by the study, not per integrator");
            }
        }
        let budgets = match params.remove(BUDGETS) {
            None => Budgets::Uniform,
            Some(Value::String(name)) => {
                Budgets::parse(&name).map_err(|e| anyhow::anyhow!("`{text}`: {e}"))?
            }
            Some(other) => bail!("`{text}`: `{BUDGETS}` is uniform or per-pixel, not {other:?}"),
        };
        let in_passes = match params.remove(PASSES) {
            None if budgets != Budgets::Uniform => {
                bail!("`{text}`: `{BUDGETS}` applies to a render in passes: add `{PASSES}=K`")
            }
            None => None,
            Some(Value::Number(n)) if n.into_f64() >= 2.0 && n.into_f64() <= 64.0 => {
                Some(InPasses {
                    passes: n.into_f64() as u32,
                    budgets,
                })
            }
            Some(other) => {
                bail!("`{text}`: `{PASSES}` is a number of passes from 2 to 64, not {other:?}")
            }
        };
        Ok(Self {
            label: text.trim().to_string(),
            spec: PluginSpec {
                kind: kind.to_string(),
                params,
            },
            in_passes,
        })
    }

    /// A choice made by the study itself (a sweep point): `kind` with `params`, labelled `label`.
    pub fn with_params(label: String, kind: &str, params: &[(&str, Value)]) -> Self {
        Self {
            label,
            spec: PluginSpec {
                kind: kind.to_string(),
                params: params
                    .iter()
                    .map(|(k, v)| (k.to_string(), v.clone()))
                    .collect(),
            },
            in_passes: None,
        }
    }

    /// A string parameter, if set (e.g. the `alpha` integrator's `mode`).
    pub fn string_param(&self, name: &str) -> Option<&str> {
        match self.spec.params.get(name) {
            Some(Value::String(s)) => Some(s),
            _ => None,
        }
    }

    /// An integer parameter, if set.
    pub fn int_param(&self, name: &str) -> Option<u64> {
        match self.spec.params.get(name) {
            Some(Value::Number(n)) => Some(n.into_f64()).filter(|v| *v >= 0.0).map(|v| v as u64),
            _ => None,
        }
    }

    /// The second-order α with integrated estimation (the paper's Table 2 method): the `alpha`
    /// integrator, or `path` with it as its first vertex's allocation.
    pub fn is_integrated_alpha(&self) -> bool {
        let integrated = matches!(
            self.string_param(alpha::MODE),
            None | Some(alpha::INTEGRATED)
        );
        integrated
            && (self.spec.kind == alpha::NAME
                || (self.is_path() && self.string_param(path::ALLOCATION) == Some(alpha::NAME)))
    }

    /// A `path` row: its budget is camera samples per pixel ([`Choice::spec_at`]).
    pub fn is_path(&self) -> bool {
        self.spec.kind == path::NAME
    }

    /// The baseline of a study of direct integrators: the balance heuristic.
    fn is_direct_baseline(&self) -> bool {
        self.spec.kind == BALANCE
    }

    /// The baseline of a study of `path` rows: `path` with the balance weighting at every vertex.
    fn is_path_baseline(&self) -> bool {
        self.is_path() && self.string_param(path::WEIGHTING) == Some(BALANCE)
    }

    /// Camera samples per pixel of this row at budget `budget`: the budget for a `path` row
    /// (`None`: the scene's own for a direct one).
    pub fn camera_samples(&self, budget: u32) -> Option<u32> {
        self.is_path().then_some(budget)
    }

    /// The plugin's spec for a budget of `samples` per light (per camera sample; in passes, over
    /// the pixel's camera samples: [`InPasses`]), with the AOV layers the study reads among
    /// those the plugin offers. A `path` row's budget is its camera samples per pixel
    /// ([`Choice::camera_samples`]): its spec keeps its own `samples`.
    pub fn spec_at(&self, samples: u32) -> Result<PluginSpec> {
        let plugin = find::<IntegratorPlugin>(&self.spec.kind)
            .map_err(|e| anyhow::anyhow!("--integrators: {e}"))?;
        if !mis::takes_samples(plugin) {
            bail!(
                "--integrators `{}`: the plugin has no `{}` parameter, so the study cannot set its budget",
                self.label,
                mis::SAMPLES
            );
        }
        let mut spec = self.spec.clone();
        if !self.is_path() {
            let per_light = match self.in_passes {
                Some(p) => (samples / p.spp()).max(1),
                None => samples,
            };
            mis::set_samples(&mut spec, per_light);
        }
        let offered = plugin.params.iter().find_map(|p| match p.kind {
            ParamKind::List { options } if p.name == mis::AOVS => Some(options),
            _ => None,
        });
        if let Some(options) = offered {
            let layers = STUDY_AOVS
                .iter()
                .filter(|name| options.contains(name))
                .map(|name| Value::String(name.to_string()))
                .collect();
            spec.params.insert(mis::AOVS.into(), Value::Seq(layers));
        }
        Ok(spec)
    }
}

/// The AOV layers the study reads when an integrator offers them.
const STUDY_AOVS: [&str; 3] = [aovs::SAMPLING_VARIANCE, aovs::ALPHA, aovs::SAMPLE_COUNTS];

/// The default integrator list: every member of the MIS family, α both ways.
pub const DEFAULT_INTEGRATORS: &str =
    "bsdf,light,balance,power,max,alpha,alpha:mode=preprocessed:alpha_samples=256";
/// The default ladder of budgets N (samples per light per camera sample).
pub const DEFAULT_BUDGETS: &str = "4,8,16,32,64,128,256";
/// The paper's budget (Tables 1 and 2): N = 256 samples per light.
pub const PAPER_BUDGET: u32 = 256;
/// The paper's pilot for the preprocessed α (Table 1): M = 4096.
pub const PAPER_PREPROCESSED_PILOT: u32 = 4096;

/// Where the reference image comes from.
#[derive(Clone, Debug)]
pub enum ReferenceSource {
    /// An EXR given by the user (one scene only).
    File(PathBuf),
    /// Rendered with the baseline ([`StudyConfig::baseline`]) at this many samples per light
    /// per pixel (camera samples per pixel for `path`), as independent shards, and cached.
    Samples(u32),
}

/// Which sweeps of α's parameters to run (at the sweep budget).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sweeps {
    /// α's clamping interval (paper Figure 2).
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

    pub fn any(&self) -> bool {
        self.clamp || self.alpha_samples || self.convergence
    }
}

/// Everything a study is asked to do.
#[derive(Clone, Debug)]
pub struct StudyConfig {
    pub scenes: Vec<PathBuf>,
    pub integrators: Vec<Choice>,
    /// The ladder of budgets N, increasing.
    pub budgets: Vec<u32>,
    /// The budget whose baseline error is each scene's target error, and whose time is its
    /// equal-time point (default: the middle of the ladder).
    pub target_budget: Option<u32>,
    /// K₀: runs (seeds) of every configuration in the first round (at least 3).
    pub runs: u32,
    /// The cap of K: the curves' runs double until the headline ratio's interval is within
    /// ±`precision` or K would exceed this.
    pub max_runs: u32,
    /// Relative half-width of the 95 % interval the K rule aims at (0.05: ±5 %).
    pub precision: f64,
    pub reference: ReferenceSource,
    /// Where rendered references are cached (default `OUT/cache`).
    pub cache_dir: Option<PathBuf>,
    /// Also run the paper's preprocessed α (M = 4096) at N = 256, for Table 1 like for like.
    pub paper_pilots: bool,
    pub sweeps: Sweeps,
    /// The budget of the sweeps (default: the target budget).
    pub sweep_budget: Option<u32>,
    /// Edge of the square pixel blocks of the jackknife, in pixels.
    pub block: u32,
    /// ε of the relative errors, as a fraction of the reference's mean luminance:
    /// V / (ref² + (fraction · mean ref)²).
    pub epsilon: f64,
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
    /// A configuration with the defaults of the command line for `scenes`, writing to `out`.
    pub fn new(scenes: Vec<PathBuf>, out: PathBuf) -> Result<Self> {
        Ok(Self {
            scenes,
            integrators: parse_integrators(DEFAULT_INTEGRATORS)?,
            budgets: parse_budgets(DEFAULT_BUDGETS)?,
            target_budget: None,
            runs: 4,
            max_runs: 16,
            precision: 0.05,
            reference: ReferenceSource::Samples(4096),
            cache_dir: None,
            paper_pilots: false,
            sweeps: Sweeps::default(),
            sweep_budget: None,
            block: 16,
            epsilon: 0.01,
            overrides: Vec::new(),
            threads: 0,
            seed: 0,
            out,
            report: None,
            notes: None,
            command: None,
        })
    }

    pub fn report_path(&self) -> PathBuf {
        self.report
            .clone()
            .unwrap_or_else(|| self.out.join("results.md"))
    }

    pub fn cache_dir(&self) -> PathBuf {
        self.cache_dir
            .clone()
            .unwrap_or_else(|| self.out.join("cache"))
    }

    /// The target budget: the one given, or the middle of the ladder.
    pub fn target_budget(&self) -> u32 {
        self.target_budget
            .unwrap_or(self.budgets[(self.budgets.len() - 1) / 2])
    }

    pub fn sweep_budget(&self) -> u32 {
        self.sweep_budget.unwrap_or_else(|| self.target_budget())
    }

    /// The run counts of the rounds: K₀, 2K₀, 4K₀, … up to the cap.
    pub fn rounds(&self) -> Vec<u32> {
        let mut rounds = vec![self.runs];
        while let Some(&last) = rounds.last()
            && last * 2 <= self.max_runs
        {
            rounds.push(last * 2);
        }
        rounds
    }

    /// The integrator whose ratio to the baseline the K rule watches: the first integrated α of
    /// the list; in a study of `path` rows without one, the first row other than the baseline.
    pub fn headline(&self) -> Option<&Choice> {
        self.headline_index().map(|i| &self.integrators[i])
    }

    /// The index of [`StudyConfig::headline`] in the list.
    pub fn headline_index(&self) -> Option<usize> {
        let alpha = self
            .integrators
            .iter()
            .position(Choice::is_integrated_alpha);
        if alpha.is_some() || !self.is_path_study() {
            return alpha;
        }
        let baseline = self.baseline().ok()?;
        (0..self.integrators.len()).find(|&i| i != baseline)
    }

    /// A study of `path` rows (all of them: [`StudyConfig::validate`] refuses a mixed list).
    pub fn is_path_study(&self) -> bool {
        self.integrators.first().is_some_and(Choice::is_path)
    }

    /// The index of the baseline in the list, against which every ratio is taken and whose
    /// error at the target budget is the target: the first `balance` of a study of direct
    /// integrators, the first `path` with `weighting=balance` of a study of `path` rows.
    pub fn baseline(&self) -> Result<usize> {
        let paths = self.integrators.iter().filter(|c| c.is_path()).count();
        if paths > 0 && paths < self.integrators.len() {
            let (first_path, first_direct) = (
                self.integrators.iter().find(|c| c.is_path()),
                self.integrators.iter().find(|c| !c.is_path()),
            );
            bail!(
                "--integrators mixes `path` rows (`{}`) with direct integrators (`{}`): they estimate different images (all light paths, or direct light only), so no ratio between them means anything; study them separately",
                first_path.map_or("", |c| &c.label),
                first_direct.map_or("", |c| &c.label)
            );
        }
        if paths > 0 {
            return self
                .integrators
                .iter()
                .position(Choice::is_path_baseline)
                .context(
                    "--integrators of `path` rows must include `path:weighting=balance`: every ratio, the target error and the equal-time point are its",
                );
        }
        self.integrators
            .iter()
            .position(Choice::is_direct_baseline)
            .context(
                "--integrators must include `balance`: every ratio, the target error and the equal-time point are the balance heuristic's",
            )
    }

    /// Checks everything that can be checked before rendering.
    pub fn validate(&self) -> Result<()> {
        if self.runs < 3 {
            bail!(
                "--runs must be at least 3: the estimator variance is measured across runs, and its interval leaves one run out"
            );
        }
        if self.max_runs < self.runs {
            bail!(
                "--max-runs ({}) is below --runs ({})",
                self.max_runs,
                self.runs
            );
        }
        if !(self.precision > 0.0 && self.precision < 1.0) {
            bail!("--precision must be in (0, 1), e.g. 0.05 for ±5 %");
        }
        if self.integrators.is_empty() {
            bail!("--integrators is empty");
        }
        if self.budgets.is_empty() {
            bail!("--budgets is empty");
        }
        if let Some(target) = self.target_budget
            && !self.budgets.contains(&target)
        {
            bail!("--target-budget {target} is not one of --budgets");
        }
        if self.block == 0 {
            bail!("--block must be at least 1 pixel");
        }
        if !(self.epsilon > 0.0 && self.epsilon.is_finite()) {
            bail!("--epsilon must be a positive fraction of the mean luminance");
        }
        let mut labels = std::collections::BTreeSet::new();
        for choice in &self.integrators {
            if !labels.insert(choice.label.as_str()) {
                bail!("--integrators lists `{}` twice", choice.label);
            }
            choice.spec_at(self.budgets[0])?;
        }
        self.baseline()?;
        if self.is_path_study() && (self.sweeps.any() || self.paper_pilots) {
            bail!(
                "--sweeps and --paper-pilots vary the direct `alpha` integrator against `balance`: they do not apply to a study of `path` rows"
            );
        }
        if let ReferenceSource::File(file) = &self.reference
            && self.scenes.len() != 1
        {
            bail!(
                "--reference `{}` is one image: give exactly one scene with it",
                file.display()
            );
        }
        if let ReferenceSource::Samples(0) = self.reference {
            bail!("--reference-samples must be positive");
        }
        if let Some(notes) = &self.notes {
            std::fs::read_to_string(notes)
                .with_context(|| format!("cannot read --notes `{}`", notes.display()))?;
        }
        Ok(())
    }
}

const BALANCE: &str = lumis_integrators::balance::NAME;

/// Splits a comma-separated list at the commas outside parentheses and brackets (an integrator's
/// parameters may hold lists: `alpha:clamp=(0.1,0.9)`).
pub fn split_list(list: &str) -> Vec<&str> {
    let (mut depth, mut start, mut items) = (0i32, 0, Vec::new());
    for (i, c) in list.char_indices() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&list[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    items.push(&list[start..]);
    items
        .into_iter()
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .collect()
}

pub fn parse_integrators(list: &str) -> Result<Vec<Choice>> {
    split_list(list).into_iter().map(Choice::parse).collect()
}

/// A ladder of budgets: positive integers, comma-separated, strictly increasing.
pub fn parse_budgets(list: &str) -> Result<Vec<u32>> {
    let budgets = list
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<u32>()
                .ok()
                .filter(|&n| n >= 1)
                .with_context(|| format!("--budgets: `{s}` is not a positive integer"))
        })
        .collect::<Result<Vec<u32>>>()?;
    if budgets.windows(2).any(|w| w[0] >= w[1]) {
        bail!("--budgets must increase strictly, e.g. 4,8,16,32");
    }
    Ok(budgets)
}
