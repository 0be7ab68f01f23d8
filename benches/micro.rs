//! Micro-benchmarks of the hot paths: BVH construction, ray queries, BSDFs, environment map
//! sampling and the per-sample cost of the adaptive-α statistics. Run with `cargo bench`
//! (`cargo bench -- bvh` for one group); docs/performance.md lists the figures measured.
//!
//! Why one file of over 600 lines: one criterion harness, one group per hot path, sharing the
//! scenes and rays they are measured on.

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use glam::{Vec2, Vec3};
use lumis::bsdf::{Bsdf, BsdfContext};
use lumis::emitter::{Emitter, ReferencePoint};
use lumis::geometry::{Geometry, Intersection, Mesh, PACKET_SIZE, Ray, RayOrigin, ShapeGeometry};
use lumis::integrator::CameraSample;
use lumis::integrators::estimator::SampleRecord;
use lumis::integrators::phase::{Observer, Phase, PhaseRole, SampleSplit};
use lumis::integrators::power::Power;
use lumis::integrators::sampling::{LightSampling, PhaseBuffers};
use lumis::integrators::second_order::SecondOrderMoments;
use lumis::integrators::shading_point::ShadingPoint;
use lumis::integrators::weighting::{Balance, PerSample, Weighting};
use lumis::math::Rgb;
use lumis::math::lanes::{DEFAULT_WIDTH, limit_width};
use lumis::sampler::Sampler;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

/// Rays (or samples) per measured batch: large enough that loop overhead vanishes, small enough
/// that a batch stays in cache.
const BATCH: usize = 4096;
/// Samples drawn at one shading point in the batch benchmarks (N = 64, half per technique).
const POINT_SAMPLES: usize = 32;
/// The batch kernels at the default width (eight lanes with AVX2), at four, and at sixteen (with
/// AVX-512; elsewhere the widest the processor has): the same results, so the ratios are what
/// the wider lanes buy.
const LANE_WIDTHS: [(&str, usize); 3] = [
    ("", DEFAULT_WIDTH),
    ("_four_lanes", 4),
    ("_sixteen_lanes", 16),
];

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// A 1000 × 500-quad height field (10⁶ triangles) with smooth bumps: a procedural stand-in for
/// a large scanned mesh, with no degenerate triangles.
fn height_field() -> Mesh {
    let (nx, nz) = (1000u32, 500u32);
    let mut mesh = Mesh::default();
    for j in 0..=nz {
        for i in 0..=nx {
            let (x, z) = (i as f32 * 0.1, j as f32 * 0.1);
            let y = (x * 0.7).sin() * (z * 1.3).cos() + 0.3 * (x * 3.1 + z * 2.3).sin();
            mesh.positions.push(Vec3::new(x, y, z));
        }
    }
    let row = nx + 1;
    for j in 0..nz {
        for i in 0..nx {
            let a = j * row + i;
            mesh.indices.push([a, a + row, a + 1]);
            mesh.indices.push([a + 1, a + row, a + row + 1]);
        }
    }
    mesh
}

fn load_mesh(path: &Path) -> Mesh {
    lumis::scene::gltf::load(path, None).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// dragon_res2 lives in the shared data directory beside the repository, not in it.
fn dragon_res2() -> Option<Mesh> {
    let path = repo("../shared/data/meshes/dragon_res2.glb");
    if path.exists() {
        Some(load_mesh(&path))
    } else {
        println!(
            "skipping dragon_res2: {} not found (it is in the shared data directory)",
            path.display()
        );
        None
    }
}

fn bvh_build(c: &mut Criterion) {
    let mut group = c.benchmark_group("bvh_build");
    group.sample_size(10);
    group.warm_up_time(Duration::from_secs(1));
    let mut meshes = vec![
        (
            "dragon_res3_48k",
            load_mesh(&repo("scenes/meshes/dragon_res3.glb")),
        ),
        ("heightfield_1m", height_field()),
    ];
    if let Some(mesh) = dragon_res2() {
        meshes.insert(1, ("dragon_res2_203k", mesh));
    }
    for (name, mesh) in meshes {
        group.throughput(Throughput::Elements(mesh.indices.len() as u64));
        group.bench_function(name, |b| {
            b.iter_batched(
                || vec![ShapeGeometry::Mesh(mesh.clone())],
                |shapes| black_box(Geometry::new(shapes)),
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

/// The corners of the mesh's bounding box.
fn mesh_bounds(mesh: &Mesh) -> (Vec3, Vec3) {
    mesh.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &p| (lo.min(p), hi.max(p)),
    )
}

/// Camera rays through a 64 × 64 grid looking at the dragon (coherent), and rays between random
/// points of its bounding box (incoherent: random origins and directions, as secondary rays).
fn ray_sets(mesh: &Mesh) -> [(&'static str, Vec<Ray>); 2] {
    let (lo, hi) = mesh_bounds(mesh);
    let (center, extent) = ((lo + hi) * 0.5, hi - lo);
    let eye = center + Vec3::new(0.0, 0.0, 2.5 * extent.max_element());
    let side = (BATCH as f32).sqrt() as usize;
    let coherent = (0..BATCH)
        .map(|i| {
            let (x, y) = (
                (i % side) as f32 / side as f32,
                (i / side) as f32 / side as f32,
            );
            let target = center + Vec3::new((x - 0.5) * extent.x, (y - 0.5) * extent.y, 0.0);
            Ray {
                origin: eye,
                direction: (target - eye).normalize(),
                t_max: f32::INFINITY,
            }
        })
        .collect();
    let mut sampler = Sampler::new(7, 0, 0);
    let mut point =
        || lo + extent * Vec3::new(sampler.next_1d(), sampler.next_1d(), sampler.next_1d());
    let incoherent = (0..BATCH)
        .map(|_| {
            let (origin, target) = (point(), point());
            Ray {
                origin,
                direction: (target - origin).normalize(),
                t_max: f32::INFINITY,
            }
        })
        .collect();
    [("coherent", coherent), ("incoherent", incoherent)]
}

/// Camera rays as a render traces them: `PACKET_SIZE` (16) jittered rays through each of 256
/// pixels (every 8th of a 256 × 64 film over the dragon, so pixels about as large as in the
/// race's dragon scene), a pixel's rays one after the other.
fn pixel_rays(mesh: &Mesh) -> Vec<Ray> {
    let (lo, hi) = mesh_bounds(mesh);
    let (center, extent) = ((lo + hi) * 0.5, hi - lo);
    let eye = center + Vec3::new(0.0, 0.0, 2.5 * extent.max_element());
    let (width, height) = (32, BATCH / PACKET_SIZE / 32);
    let mut sampler = Sampler::new(3, 0, 0);
    (0..BATCH)
        .map(|i| {
            let pixel = i / PACKET_SIZE;
            let jitter = sampler.next_2d();
            let x = ((8 * (pixel % width)) as f32 + jitter.x) / (8 * width) as f32;
            let y = ((8 * (pixel / width)) as f32 + jitter.y) / (8 * height) as f32;
            let target = center + Vec3::new((x - 0.5) * extent.x, (y - 0.5) * extent.y, 0.0);
            Ray {
                origin: eye,
                direction: (target - eye).normalize(),
                t_max: f32::INFINITY,
            }
        })
        .collect()
}

fn ray_queries(c: &mut Criterion) {
    let mesh = load_mesh(&repo("scenes/meshes/dragon_res3.glb"));
    let sets = ray_sets(&mesh);
    let pixels = pixel_rays(&mesh);
    let (lo, hi) = mesh_bounds(&mesh);
    let geometry = Geometry::new(vec![ShapeGeometry::Mesh(mesh)]);
    let mut group = c.benchmark_group("rays_dragon_res3");
    group.throughput(Throughput::Elements(BATCH as u64));
    for (name, rays) in &sets {
        let hits = rays
            .iter()
            .filter(|r| geometry.intersect(r).is_some())
            .count();
        let blocked = rays.iter().filter(|r| geometry.occluded(r)).count();
        assert_eq!(blocked, hits, "{name}: occluded and intersect disagree");
        println!("{name}: {hits} of {BATCH} rays hit");
        group.bench_function(format!("closest_hit_{name}"), |b| {
            b.iter(|| {
                for ray in rays {
                    black_box(geometry.intersect(ray));
                }
            })
        });
        group.bench_function(format!("occlusion_{name}"), |b| {
            b.iter(|| {
                for ray in rays {
                    black_box(geometry.occluded(ray));
                }
            })
        });
    }
    // Shadow rays from the points the coherent camera rays hit toward a point above and in
    // front of the mesh, as a render spawns them: tested in full, and without the triangle
    // under each origin (`occluded_by_others` with the point left, what the integrators ask since the nineteenth
    // round). Both answer alike (asserted).
    let light = (lo + hi) * 0.5 + (hi - lo) * Vec3::new(0.3, 1.5, 1.5);
    let shadows: Vec<(Intersection, Ray)> = (sets[0].1.iter())
        .filter_map(|ray| {
            let hit = geometry.intersect(ray)?;
            Some((
                hit,
                RayOrigin::toward(&hit, -ray.direction).ray_to(&hit, light),
            ))
        })
        .collect();
    let blocked = |query: &dyn Fn(&Intersection, &Ray) -> bool| {
        shadows.iter().filter(|(hit, ray)| query(hit, ray)).count()
    };
    let full = blocked(&|_, ray| geometry.occluded(ray));
    assert_eq!(
        full,
        blocked(&|hit, ray| geometry.occluded_by_others(ray, None, Some(hit)))
    );
    println!("shadow rays from hits: {full} of {} blocked", shadows.len());
    group.throughput(Throughput::Elements(shadows.len() as u64));
    group.bench_function("shadow_from_hits_full", |b| {
        b.iter(|| {
            for (_, ray) in &shadows {
                black_box(geometry.occluded(ray));
            }
        })
    });
    group.bench_function("shadow_from_hits_leaving", |b| {
        b.iter(|| {
            for (hit, ray) in &shadows {
                black_box(geometry.occluded_by_others(ray, None, Some(hit)));
            }
        })
    });
    group.throughput(Throughput::Elements(BATCH as u64));
    // A pixel's camera rays traced alone and as one packet (what the render loop does).
    group.bench_function("closest_hit_pixels_alone", |b| {
        b.iter(|| {
            for ray in &pixels {
                black_box(geometry.intersect(ray));
            }
        })
    });
    let mut hits = vec![None; PACKET_SIZE];
    group.bench_function("closest_hit_pixels_packets", |b| {
        b.iter(|| {
            for packet in pixels.chunks(PACKET_SIZE) {
                geometry.intersect_packet(packet, &mut hits);
                black_box(&hits);
            }
        })
    });
    group.finish();
}

/// The context of the BSDF benchmarks' shading points (one at a time, untextured, from the
/// front).
const FRONT: BsdfContext = BsdfContext::FRONT;

/// A BSDF built through the registry, as a scene builds it.
fn bsdf(spec: &str) -> Arc<dyn Bsdf> {
    lumis::link_plugins();
    let spec: lumis::scene::description::PluginSpec =
        ron::from_str(spec).expect("valid plugin description");
    let plugin =
        lumis::registry::find::<lumis::registry::BsdfPlugin>(&spec.kind).expect("built-in BSDF");
    let mut params = lumis::params::Params::new(spec.kind.clone(), plugin.params, spec.params)
        .expect("valid parameters");
    (plugin.create)(&mut params).expect("BSDF builds")
}

fn bsdfs(c: &mut Criterion) {
    // The measured BSDF tabulates a rough glossy one in a MERL file.
    let dir = tempfile::tempdir().expect("temporary directory");
    let merl = dir.path().join("glossy.binary");
    let glossy = bsdf("(type: \"glossy\", roughness: 0.2, specular: 0.5, diffuse: 0.3)");
    lumis::bsdfs::measured::write_merl(&merl, |wi, wo| glossy.eval(&FRONT, wo, wi) / wi.z)
        .expect("MERL file written");
    let models = [
        ("diffuse", bsdf("(type: \"diffuse\", reflectance: 0.5)")),
        ("glossy", glossy),
        ("mirror", bsdf("(type: \"mirror\")")),
        (
            "measured",
            bsdf(&format!(
                "(type: \"measured\", file: {:?})",
                merl.display().to_string()
            )),
        ),
    ];
    // Directions above the surface and random numbers, drawn once.
    let mut sampler = Sampler::new(3, 0, 0);
    let inputs: Vec<(Vec3, Vec3, f32, Vec2)> = (0..BATCH)
        .map(|_| {
            let mut hemisphere =
                || lumis::math::warp::square_to_cosine_hemisphere(sampler.next_2d()).normalize();
            let (wo, wi) = (hemisphere(), hemisphere());
            (wo, wi, sampler.next_1d(), sampler.next_2d())
        })
        .collect();
    let mut group = c.benchmark_group("bsdf");
    group.throughput(Throughput::Elements(BATCH as u64));
    for (name, model) in &models {
        group.bench_function(format!("{name}_sample"), |b| {
            b.iter(|| {
                for &(wo, _, u_lobe, u) in &inputs {
                    black_box(model.sample(&FRONT, wo, u_lobe, u));
                }
            })
        });
        group.bench_function(format!("{name}_eval"), |b| {
            b.iter(|| {
                for &(wo, wi, _, _) in &inputs {
                    black_box(model.eval(&FRONT, wo, wi));
                }
            })
        });
        group.bench_function(format!("{name}_pdf"), |b| {
            b.iter(|| {
                for &(wo, wi, _, _) in &inputs {
                    black_box(model.pdf(&FRONT, wo, wi));
                }
            })
        });
        // The samples of one shading point, POINT_SAMPLES at a time with one ωo: one call each,
        // then one batch call (which gives the same results, bit for bit).
        let at_points = || {
            inputs
                .chunks(POINT_SAMPLES)
                .map(|chunk| (chunk[0].0, chunk))
        };
        group.bench_function(format!("{name}_sample_at_points"), |b| {
            b.iter(|| {
                for (wo, chunk) in at_points() {
                    for &(_, _, u_lobe, u) in chunk {
                        black_box(model.sample(&FRONT, wo, u_lobe, u));
                    }
                }
            })
        });
        let numbers: Vec<(f32, Vec2)> = inputs.iter().map(|&(_, _, ul, u)| (ul, u)).collect();
        let directions: Vec<Vec3> = inputs.iter().map(|&(_, wi, _, _)| wi).collect();
        let mut samples = vec![None; POINT_SAMPLES];
        let mut wos = vec![Vec3::Z; POINT_SAMPLES];
        for (lanes, width) in LANE_WIDTHS {
            limit_width(width);
            group.bench_function(format!("{name}_sample_batch{lanes}"), |b| {
                b.iter(|| {
                    for (wo, chunk) in at_points().zip(numbers.chunks(POINT_SAMPLES)) {
                        wos.fill(wo.0);
                        let n = chunk.len();
                        model.sample_batch(&[FRONT], &wos[..n], chunk, &mut samples[..n]);
                        black_box(&samples);
                    }
                })
            });
        }
        limit_width(DEFAULT_WIDTH);
        group.bench_function(format!("{name}_eval_pdf_at_points"), |b| {
            b.iter(|| {
                for (wo, chunk) in at_points() {
                    for &(_, wi, _, _) in chunk {
                        black_box(model.eval_pdf(&FRONT, wo, wi));
                    }
                }
            })
        });
        let mut values = vec![(Rgb::ZERO, 0.0); POINT_SAMPLES];
        for (lanes, width) in LANE_WIDTHS {
            limit_width(width);
            group.bench_function(format!("{name}_eval_pdf_batch{lanes}"), |b| {
                b.iter(|| {
                    for (wo, chunk) in at_points().zip(directions.chunks(POINT_SAMPLES)) {
                        wos.fill(wo.0);
                        let n = chunk.len();
                        model.eval_pdf_batch(&[FRONT], &wos[..n], chunk, &mut values[..n]);
                        black_box(&values);
                    }
                })
            });
        }
        limit_width(DEFAULT_WIDTH);
    }
    group.finish();
}

/// Area lights sampled from points of the bundled scenes: the Veach scene's sphere lights
/// (cone sampling) and the Cornell box's quad (two triangles), one call per sample against one
/// batch call per point.
fn area_lights(c: &mut Criterion) {
    let mut group = c.benchmark_group("area_light");
    group.throughput(Throughput::Elements(BATCH as u64));
    for (name, scene_file, light) in [
        ("sphere", "scenes/veach.ron", 1),
        ("quad", "scenes/cornell.ron", 0),
    ] {
        let loaded = lumis::scene::load::load_scene(&repo(scene_file), &[])
            .unwrap_or_else(|e| panic!("{e}"));
        let scene = &loaded.scene;
        let emitter = scene.emitters[light].as_ref();
        // Points the camera sees, POINT_SAMPLES samples at each.
        let points: Vec<ReferencePoint> = (0..BATCH / POINT_SAMPLES)
            .filter_map(|i| {
                let pixel = glam::UVec2::new(
                    (i as u32 * 37) % scene.width,
                    (i as u32 * 53) % scene.height,
                );
                let hit = scene.intersect(&CameraSample::new(scene, pixel, 0).ray)?;
                Some(ReferencePoint {
                    position: hit.position,
                })
            })
            .collect();
        let mut sampler = Sampler::new(9, 0, 0);
        let us: Vec<Vec2> = (0..points.len() * POINT_SAMPLES)
            .map(|_| sampler.next_2d())
            .collect();
        group.bench_function(format!("{name}_sample_direction"), |b| {
            b.iter(|| {
                for (point, us) in points.iter().zip(us.chunks(POINT_SAMPLES)) {
                    for &u in us {
                        black_box(emitter.sample_direction(point, u));
                    }
                }
            })
        });
        let mut samples = vec![None; POINT_SAMPLES];
        for (lanes, width) in LANE_WIDTHS {
            limit_width(width);
            group.bench_function(format!("{name}_sample_direction_batch{lanes}"), |b| {
                b.iter(|| {
                    for (point, us) in points.iter().zip(us.chunks(POINT_SAMPLES)) {
                        let references = [*point; POINT_SAMPLES];
                        emitter.sample_direction_batch(&references, us, &mut samples);
                        black_box(&samples);
                    }
                })
            });
        }
        limit_width(DEFAULT_WIDTH);
    }
    group.finish();
}

fn envmap(c: &mut Criterion) {
    use lumis::emitters::envmap::{EnvironmentMap, Interpolation, MapSettings};
    let path = repo("scenes/envmaps/studio.exr");
    let image = lumis::image_io::read_exr_rgb(&path).expect("studio.exr reads");
    let reference = ReferencePoint {
        position: Vec3::ZERO,
    };
    let mut sampler = Sampler::new(5, 0, 0);
    let us: Vec<Vec2> = (0..BATCH).map(|_| sampler.next_2d()).collect();
    let directions: Vec<Vec3> = us
        .iter()
        .map(|&u| lumis::math::warp::square_to_cosine_hemisphere(u).normalize())
        .collect();
    // The race's map is 2048 × 1022: the studio map with each pixel doubled both ways, and 2^20
    // queries a round, so that its tables (about 50 MB) are read from memory as in a render,
    // where the 4096 queries of the other groups find them in the caches.
    let doubled: Vec<Vec3> = (0..image.width * image.height * 4)
        .map(|i| {
            let (x, y) = (i % (2 * image.width) / 2, i / (2 * image.width) / 2);
            image.pixels[y * image.width + x]
        })
        .collect();
    let mut sampler = Sampler::new(6, 0, 0);
    let cold_us: Vec<Vec2> = (0..1 << 20).map(|_| sampler.next_2d()).collect();
    let cold_directions: Vec<Vec3> = (0..1 << 20)
        .map(|_| {
            let (a, b) = (sampler.next_2d(), sampler.next_2d());
            Vec3::new(a.x - 0.5, a.y - 0.5, b.x - 0.5).normalize()
        })
        .collect();
    for (name, interpolation, (width, height, pixels), (us, directions)) in [
        (
            "envmap_studio_1024x512",
            Interpolation::Nearest,
            (image.width, image.height, &image.pixels),
            (&us, &directions),
        ),
        (
            "envmap_studio_1024x512_bilinear",
            Interpolation::Bilinear,
            (image.width, image.height, &image.pixels),
            (&us, &directions),
        ),
        (
            "envmap_studio_2048x1024_from_memory",
            Interpolation::Nearest,
            (2 * image.width, 2 * image.height, &doubled),
            (&cold_us, &cold_directions),
        ),
    ] {
        let settings = MapSettings {
            interpolation,
            ..MapSettings::default()
        };
        let map = EnvironmentMap::with_settings(width, height, pixels.clone(), &settings)
            .expect("studio.exr makes a map");
        let mut group = c.benchmark_group(name);
        group.throughput(Throughput::Elements(us.len() as u64));
        group.bench_function("sample_direction", |b| {
            b.iter(|| {
                for &u in us {
                    black_box(map.sample_direction(&reference, u));
                }
            })
        });
        // In batches of POINT_SAMPLES, as a shading point's light samples are drawn.
        let mut samples = vec![None; POINT_SAMPLES];
        for (lanes, width) in LANE_WIDTHS {
            limit_width(width);
            group.bench_function(format!("sample_direction_batch{lanes}"), |b| {
                b.iter(|| {
                    for us in us.chunks(POINT_SAMPLES) {
                        let out = &mut samples[..us.len()];
                        map.sample_direction_batch(std::slice::from_ref(&reference), us, out);
                        black_box(&out);
                    }
                })
            });
        }
        limit_width(DEFAULT_WIDTH);
        group.bench_function("pdf_direction", |b| {
            b.iter(|| {
                for &d in directions {
                    black_box(map.pdf_direction(&reference, d, None));
                }
            })
        });
        group.bench_function("eval", |b| {
            b.iter(|| {
                for &d in directions {
                    black_box(map.eval(d, None));
                }
            })
        });
        // What a BSDF sample that reaches the map asks: before and since `eval_pdf`.
        group.bench_function("eval_then_pdf_direction", |b| {
            b.iter(|| {
                for &d in directions {
                    black_box((map.eval(d, None), map.pdf_direction(&reference, d, None)));
                }
            })
        });
        group.bench_function("eval_pdf", |b| {
            b.iter(|| {
                for &d in directions {
                    black_box(map.eval_pdf(&reference, d, None));
                }
            })
        });
        // In batches of POINT_SAMPLES, as a packet's BSDF samples that reached the map are
        // looked up.
        let mut values = vec![(Rgb::ZERO, 0.0); POINT_SAMPLES];
        for (lanes, width) in LANE_WIDTHS {
            limit_width(width);
            group.bench_function(format!("eval_pdf_batch{lanes}"), |b| {
                b.iter(|| {
                    for directions in directions.chunks(POINT_SAMPLES) {
                        let out = &mut values[..directions.len()];
                        map.eval_pdf_batch(std::slice::from_ref(&reference), directions, out);
                        black_box(&out);
                    }
                })
            });
        }
        limit_width(DEFAULT_WIDTH);
        group.finish();
    }
}

/// The α statistics' cost per sample: the same balance-weighted phase at a shading point of the
/// Veach scene (a glossy plate, four sphere lights) with and without the observer that
/// accumulates Î₁ and Î₂.
fn alpha_estimator(c: &mut Criterion) {
    lumis::link_plugins();
    let loaded = lumis::scene::load::load_scene(&repo("scenes/veach.ron"), &[])
        .unwrap_or_else(|e| panic!("{e}"));
    let scene = &loaded.scene;
    // A pixel on the second plate, lit by every light.
    let pixel = glam::UVec2::new(160, 150);
    let ray = CameraSample::new(scene, pixel, 0).ray;
    let hit = scene.intersect(&ray).expect("the camera sees a plate");
    let sp = ShadingPoint::new(scene, &hit, -ray.direction);
    let split = SampleSplit::new(0.5, 64);
    let balance = PerSample(Balance);
    let mut buffers = PhaseBuffers::default();
    let mut group = c.benchmark_group("alpha_estimator");
    group.throughput(Throughput::Elements(
        (split.total() as usize * scene.emitters.len()) as u64,
    ));
    let mut run = |name: &str, observer: &mut dyn Observer| {
        group.bench_function(name, |b| {
            let mut index = 0;
            b.iter(|| {
                index += 1;
                let mut sampler = Sampler::new(0, 0, index);
                for light in 0..scene.emitters.len() {
                    let mut sampling =
                        LightSampling::new(scene, &sp, light, pixel, &mut sampler, &mut buffers);
                    black_box(sampling.phase(split, PhaseRole::ESTIMATE, &balance, observer));
                }
            })
        });
    };
    run("balance", &mut ());
    let mut moments = SecondOrderMoments::default();
    run("balance_with_alpha_terms", &mut moments);
    black_box(moments);
    // The observer alone, on the four lights' phases of one camera sample, drawn once: the
    // difference of the two runs above is lost in their run-to-run spread.
    let mut recorded = RecordedPhases::default();
    let mut sampler = Sampler::new(0, 0, 0);
    for light in 0..scene.emitters.len() {
        let mut sampling = LightSampling::new(scene, &sp, light, pixel, &mut sampler, &mut buffers);
        sampling.phase(split, PhaseRole::ESTIMATE, &balance, &mut recorded);
    }
    group.bench_function("alpha_terms_alone", |b| {
        b.iter(|| {
            let mut moments = SecondOrderMoments::default();
            for (phase, contributions) in recorded.phases(pixel, split) {
                moments.observe(black_box(&phase), contributions);
            }
            black_box(moments)
        })
    });
    group.finish();
    weighting(c, scene, &sp, pixel, &mut buffers);
}

/// The `power` weighting alone on recorded phases at the Veach plate: 256 phases of one sample
/// per technique (the race scenes' `samples: 2`, weighed record by record) and the four lights'
/// phases of 32 + 32 samples (weighed in lanes).
fn weighting(
    c: &mut Criterion,
    scene: &lumis::scene::Scene,
    sp: &ShadingPoint,
    pixel: glam::UVec2,
    buffers: &mut PhaseBuffers,
) {
    let power = PerSample(Power);
    let mut group = c.benchmark_group("weighting");
    for (name, samples, phases) in [("power_1_plus_1", 2, 256), ("power_32_plus_32", 64, 4)] {
        let split = SampleSplit::new(0.5, samples);
        let mut recorded = RecordedPhases::default();
        let mut sampler = Sampler::new(0, 0, 0);
        for index in 0..phases {
            let light = index % scene.emitters.len();
            let mut sampling = LightSampling::new(scene, sp, light, pixel, &mut sampler, buffers);
            sampling.phase(split, PhaseRole::ESTIMATE, &power, &mut recorded);
        }
        group.throughput(Throughput::Elements(phases as u64 * samples as u64));
        group.bench_function(name, |b| {
            let mut contributions = Vec::new();
            b.iter(|| {
                let mut sum = Rgb::ZERO;
                for (phase, _) in recorded.phases(pixel, split) {
                    contributions.clear();
                    contributions.resize(phase.records.len(), Rgb::ZERO);
                    sum += power.weigh(black_box(&phase), &mut contributions);
                }
                black_box(sum)
            })
        });
    }
    group.finish();
}

/// Copies of the phases an observer is shown: their records and contributions.
#[derive(Default)]
struct RecordedPhases {
    phases: Vec<(Vec<SampleRecord>, Vec<Rgb>)>,
}

impl RecordedPhases {
    /// The recorded phases again, as light 0's at `pixel` with `split`, with their
    /// contributions.
    fn phases(
        &self,
        pixel: glam::UVec2,
        split: SampleSplit,
    ) -> impl Iterator<Item = (Phase<'_>, &[Rgb])> {
        self.phases.iter().map(move |(records, contributions)| {
            let phase = Phase {
                pixel,
                light: 0,
                split,
                role: PhaseRole::ESTIMATE,
                records,
            };
            (phase, contributions.as_slice())
        })
    }
}

impl Observer for RecordedPhases {
    fn observe(&mut self, phase: &Phase, contributions: &[Rgb]) {
        self.phases
            .push((phase.records.to_vec(), contributions.to_vec()));
    }
}

criterion_group!(
    name = benches;
    // Short runs: the whole suite takes about two minutes, and the batches are long enough that
    // criterion's confidence intervals stay within a few percent.
    config = Criterion::default()
        .warm_up_time(Duration::from_millis(500))
        .measurement_time(Duration::from_secs(2));
    targets = bvh_build, ray_queries, bsdfs, area_lights, envmap, alpha_estimator
);
criterion_main!(benches);
