//! The MIS methods against the balance heuristic on real scenes: per scene and method, the
//! estimator variance (across K independent runs, per pixel, in luminance, averaged over the
//! pixels; camera rays through the pixel centres, as `lumis study`), the CPU time of a run
//! (preprocess and render, one thread) and the efficiency 1/(variance × time), each as a ratio
//! to balance's with a 95 % bootstrap interval. Runs are interleaved (round k renders every
//! method with seed k) so that the load of a shared machine hits every method alike.
//! docs/integrators.md quotes its tables.
//!
//! ```text
//! cargo bench --bench methods -- [--runs K] [--size W] [--samples N] [--spp S] SCENE...
//! cargo bench --bench methods -- --costs [--runs K] [--size W] SCENE...
//! cargo bench --bench methods -- --compensation [--runs K] ... SCENE...
//! ```
//!
//! With `--compensation` (scenes whose first `emitters` entry is an `envmap`), it compares a few
//! methods with the map's MIS compensation off and on, each against balance without it.
//!
//! With `--costs`, it prints instead what `cost_alpha` measures on each scene: per light, the
//! ratio c_B / c_L of the costs of a BSDF and a light sample over K measurements (their median
//! and range), and the time one measurement takes.
//!
//! Intervals: the variance ratio Σ_p v_p / Σ_p v_p^balance (v_p a pixel's sample variance over
//! the K runs) is resampled over 8 × 8-pixel blocks (pilot-based methods correlate neighbouring
//! pixels), the time ratio over the rounds (paired: both methods ran in the same round); the
//! efficiency ratio's interval comes from their product under joint resampling. Percentile
//! intervals from 2000 resamples.

use std::path::{Path, PathBuf};

/// A compared method: label, integrator type, extra overrides (scene paths).
type Method = (&'static str, &'static str, &'static [&'static str]);

/// Methods compared.
const METHODS: &[Method] = &[
    ("balance", "balance", &[]),
    ("light", "light", &[]),
    ("alpha (integrated)", "alpha", &[]),
    ("exact_alpha (integrated)", "exact_alpha", &[]),
    (
        "exact_alpha (stratified)",
        "exact_alpha",
        &["integrator.variance=\"stratified\""],
    ),
    ("cost_alpha", "cost_alpha", &[]),
    ("optimal_mis (direct)", "optimal_mis", &[]),
    (
        "optimal_mis (progressive)",
        "optimal_mis",
        &["integrator.mode=\"progressive\""],
    ),
    ("variance_aware", "variance_aware", &[]),
    ("pooled_alpha", "pooled_alpha", &[]),
];

/// With `--compensation`: MIS compensation of the scene's first `emitters` entry (an `envmap`),
/// off and on, under a few methods.
const COMPENSATION: &str = "emitters[0].compensation=true";
const COMPENSATION_METHODS: &[Method] = &[
    ("balance", "balance", &[]),
    ("balance, compensated", "balance", &[COMPENSATION]),
    ("alpha (integrated)", "alpha", &[]),
    ("alpha, compensated", "alpha", &[COMPENSATION]),
    ("exact_alpha (integrated)", "exact_alpha", &[]),
    ("exact_alpha, compensated", "exact_alpha", &[COMPENSATION]),
    ("optimal_mis (direct)", "optimal_mis", &[]),
    ("optimal_mis, compensated", "optimal_mis", &[COMPENSATION]),
];
const BLOCK: usize = 8;
const RESAMPLES: usize = 2000;

struct Options {
    runs: usize,
    size: u32,
    samples: u32,
    spp: u32,
    costs: bool,
    compensation: bool,
    scenes: Vec<PathBuf>,
}

fn options() -> Result<Options, String> {
    let mut o = Options {
        runs: 8,
        size: 64,
        samples: 32,
        spp: 1,
        costs: false,
        compensation: false,
        scenes: Vec::new(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = |name: &str| -> Result<u64, String> {
            args.next()
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| format!("{name} needs a positive integer"))
        };
        match arg.as_str() {
            "--bench" => {}
            "--runs" => o.runs = value("--runs")? as usize,
            "--size" => o.size = value("--size")? as u32,
            "--samples" => o.samples = value("--samples")? as u32,
            "--spp" => o.spp = value("--spp")? as u32,
            "--costs" => o.costs = true,
            "--compensation" => o.compensation = true,
            flag if flag.starts_with("--") => return Err(format!("unknown option {flag}")),
            scene => o.scenes.push(from_repository(scene)),
        }
    }
    if o.runs < 3 || o.size == 0 || o.samples == 0 || o.spp == 0 {
        return Err("need --runs ≥ 3 and positive --size, --samples, --spp".into());
    }
    Ok(o)
}

fn cpu_time() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid pointer.
    if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut t) } == 0 {
        t.tv_sec as f64 + t.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// One run: the image's luminance per pixel and the CPU time of preprocess + render.
fn run(
    o: &Options,
    scene: &std::path::Path,
    method: &Method,
    seed: usize,
) -> Result<(Vec<f64>, f64), String> {
    let mut overrides = vec![
        format!("film.width={}", o.size),
        format!("film.height={}", o.size),
        format!("sampler.spp={}", o.spp),
        format!("sampler.seed={}", 1000 + seed),
        // Every run shades the same points (as `lumis study`): the variance is the lighting's,
        // not the camera jitter's, which is the same for every method.
        "sampler.jitter=false".to_string(),
        format!("integrator.type={}", method.1),
        format!("integrator.samples={}", o.samples),
    ];
    overrides.extend(method.2.iter().map(|p| p.to_string()));
    let mut loaded = lumis::scene::load::load_scene(scene, &overrides)
        .map_err(|e| format!("{}: {e}", scene.display()))?;
    let start = cpu_time();
    loaded.integrator.preprocess(&loaded.scene);
    let (film, _) = lumis::render::render(&loaded.scene, loaded.integrator.as_ref(), 1, &|_| {})
        .map_err(|e| e.to_string())?;
    let time = cpu_time() - start;
    let image = film
        .color
        .iter()
        .map(|c| lumis::math::luminance(*c) as f64)
        .collect();
    Ok((image, time))
}

/// `cost_alpha`'s measurement, K times: per light, c_B / c_L.
fn costs(o: &Options, scene: &std::path::Path) -> Result<(), String> {
    let overrides = vec![
        format!("film.width={}", o.size),
        format!("film.height={}", o.size),
    ];
    let loaded = lumis::scene::load::load_scene(scene, &overrides)
        .map_err(|e| format!("{}: {e}", scene.display()))?;
    let mut ratios: Vec<Vec<f64>> = Vec::new();
    let mut seconds = Vec::new();
    for _ in 0..o.runs {
        let start = cpu_time();
        let costs = lumis::integrators::pilot::measure_costs(&loaded.scene, 48, 8);
        seconds.push(cpu_time() - start);
        ratios.resize(costs.len(), Vec::new());
        for (light, c) in costs.iter().enumerate() {
            if let Some(c) = c {
                ratios[light].push(c.bsdf / c.light);
            }
        }
    }
    seconds.sort_by(f64::total_cmp);
    println!(
        "\n{} ({}×{}): one measurement takes {:.3} s (median of {})",
        scene.display(),
        o.size,
        o.size,
        seconds[seconds.len() / 2],
        o.runs
    );
    for (light, r) in ratios.iter_mut().enumerate().filter(|(_, r)| !r.is_empty()) {
        r.sort_by(f64::total_cmp);
        println!(
            "light {light}: c_B / c_L median {:.3}, range [{:.3}, {:.3}] over {} measurements",
            r[r.len() / 2],
            r[0],
            r[r.len() - 1],
            r.len()
        );
    }
    Ok(())
}

/// A small deterministic generator for the resampling (xorshift64*).
struct Rng(u64);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) % n as u64) as usize
    }
}

/// Per pixel, the sample variance over the runs.
fn pixel_variances(images: &[Vec<f64>]) -> Vec<f64> {
    let k = images.len() as f64;
    (0..images[0].len())
        .map(|p| {
            let mean = images.iter().map(|im| im[p]).sum::<f64>() / k;
            images.iter().map(|im| (im[p] - mean).powi(2)).sum::<f64>() / (k - 1.0)
        })
        .collect()
}

/// Sums of `values` per 8 × 8 block of a `size` × `size` image.
fn block_sums(values: &[f64], size: usize) -> Vec<f64> {
    let blocks = size.div_ceil(BLOCK);
    let mut sums = vec![0.0; blocks * blocks];
    for (p, v) in values.iter().enumerate() {
        let (x, y) = (p % size, p / size);
        sums[(y / BLOCK) * blocks + x / BLOCK] += v;
    }
    sums
}

/// Cargo runs a benchmark in its package's folder (benches/): relative scene paths are taken
/// from the repository's root, where the documented commands are typed.
fn from_repository(scene: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(scene)
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

fn main() {
    let o = match options() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("methods: {e}");
            std::process::exit(2);
        }
    };
    lumis::link_plugins();
    if o.costs {
        for scene in &o.scenes {
            if let Err(e) = costs(&o, scene) {
                eprintln!("methods: {e}");
                std::process::exit(1);
            }
        }
        return;
    }
    let methods = if o.compensation {
        COMPENSATION_METHODS
    } else {
        METHODS
    };
    for scene in &o.scenes {
        // images[method][run], times[method][run]
        let mut images = vec![Vec::new(); methods.len()];
        let mut times = vec![Vec::new(); methods.len()];
        for round in 0..o.runs {
            for (m, method) in methods.iter().enumerate() {
                match run(&o, scene, method, round) {
                    Ok((image, time)) => {
                        images[m].push(image);
                        times[m].push(time);
                    }
                    Err(e) => {
                        eprintln!("methods: {e}");
                        std::process::exit(1);
                    }
                }
            }
            eprintln!("{}: round {} of {}", scene.display(), round + 1, o.runs);
        }
        let size = o.size as usize;
        let blocks: Vec<Vec<f64>> = images
            .iter()
            .map(|im| block_sums(&pixel_variances(im), size))
            .collect();
        println!(
            "\n{} ({}×{}, {} spp, N = {}, K = {} runs; balance: mean pixel variance {:.4e}, {:.2} s per run)\n",
            scene.display(),
            o.size,
            o.size,
            o.spp,
            o.samples,
            o.runs,
            blocks[0].iter().sum::<f64>() / (size * size) as f64,
            times[0].iter().sum::<f64>() / o.runs as f64
        );
        println!("| method | variance / balance | time / balance | efficiency / balance |");
        println!("|---|---|---|---|");
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        for m in 0..methods.len() {
            let ratio = |block_pick: &[usize], run_pick: &[usize]| {
                let v: f64 = block_pick.iter().map(|&b| blocks[m][b]).sum::<f64>()
                    / block_pick.iter().map(|&b| blocks[0][b]).sum::<f64>();
                let t: f64 = run_pick.iter().map(|&r| times[m][r]).sum::<f64>()
                    / run_pick.iter().map(|&r| times[0][r]).sum::<f64>();
                (v, t, 1.0 / (v * t))
            };
            let all_blocks: Vec<usize> = (0..blocks[0].len()).collect();
            let all_runs: Vec<usize> = (0..o.runs).collect();
            let point = ratio(&all_blocks, &all_runs);
            let mut samples = [Vec::new(), Vec::new(), Vec::new()];
            for _ in 0..RESAMPLES {
                let b: Vec<usize> = (0..all_blocks.len())
                    .map(|_| rng.below(all_blocks.len()))
                    .collect();
                let r: Vec<usize> = (0..o.runs).map(|_| rng.below(o.runs)).collect();
                let (v, t, e) = ratio(&b, &r);
                samples[0].push(v);
                samples[1].push(t);
                samples[2].push(e);
            }
            let mut cell = |i: usize, value: f64| {
                let s = &mut samples[i];
                s.sort_by(f64::total_cmp);
                format!(
                    "{value:.3} [{:.3}, {:.3}]",
                    percentile(s, 0.025),
                    percentile(s, 0.975)
                )
            };
            let (variance, time, efficiency) =
                (cell(0, point.0), cell(1, point.1), cell(2, point.2));
            println!("| {} | {variance} | {time} | {efficiency} |", methods[m].0);
        }
    }
}
