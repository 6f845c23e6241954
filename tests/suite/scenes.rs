//! Every scene in `scenes/` parses, runs (in preview size) on the CPU and on
//! the GPU, writes the files of the output contract, and the two backends
//! agree; and the output directory is never left half-written.

use std::path::{Path, PathBuf};

use reeb::backend::Engine;
use reeb::num::precision::Precision;
use reeb::output::run::{run_scene, RunOptions, TaskOptions};
use reeb::scene::{BackendChoice, Scene};

use crate::common;
use common::gpu;

fn scenes() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> =
        std::fs::read_dir(Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
    v.sort();
    v
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("reeb-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    d
}

#[test]
fn every_scene_runs_on_the_cpu_and_writes_its_files() {
    let all = scenes();
    assert!(all.len() >= 10, "{all:?}");
    for path in all {
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let small = scene.preview(3, 300);
        let out = tmp(&small.name);
        let opts = RunOptions {
            out: Some(out.clone()),
            task: TaskOptions {
                backend: Some(BackendChoice::Cpu),
                ..TaskOptions::default()
            },
            ..RunOptions::default()
        };
        let report =
            run_scene(&small, &opts).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        for key in [
            "reeb_version",
            "scene",
            "backend",
            "adapter",
            "precision",
            "ensemble_size",
            "steps",
            "integration_seconds",
            "traj_steps_per_s",
            "status",
        ] {
            assert!(
                summary.get(key).is_some(),
                "{}: summary.json lacks {key}",
                path.display()
            );
        }
        assert_eq!(
            summary["ensemble_size"].as_u64().unwrap() as usize,
            small.ensemble_size()
        );
        for f in ["status.npy", "status_step.npy"] {
            assert!(out.join(f).exists(), "{}: no {f}", path.display());
        }
        for v in &small.observers.final_vars {
            assert!(out.join(format!("final_{}.npy", v.name)).exists());
        }
        for a in &small.axes {
            assert!(out.join(format!("axis_{}.npy", a.name)).exists());
        }
        if small.observers.poincare.is_some() {
            assert!(
                out.join("poincare_count.npy").exists() && out.join("poincare.png").exists(),
                "{}",
                path.display()
            );
        }
        if small.observers.cycle.is_some() {
            assert!(
                out.join("cycle_amplitude.npy").exists() && out.join("cycle_period.npy").exists()
            );
        }
        assert!(
            std::fs::read_dir(&out).unwrap().any(|e| e
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "png")),
            "{}: no picture",
            path.display()
        );
        assert!(!report.line.is_empty());
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[test]
fn every_scene_agrees_between_cpu_and_gpu() {
    let Some(ctx) = gpu() else { return };
    for path in scenes() {
        let scene = Scene::load(&path).unwrap().preview(3, 300);
        let f64_ok = scene.precision == Precision::F32 || ctx.shader_f64;
        if !f64_ok {
            continue;
        }
        let engine = Engine::Gpu(Box::new(reeb::backend::gpu::GpuContext::new().unwrap()));
        for sub in scene.sub_runs().unwrap() {
            let (c, g) = match scene.precision {
                Precision::F32 => {
                    let c = Engine::Cpu
                        .run::<f32>(&sub.plan, None)
                        .unwrap()
                        .observations
                        .convert::<f64>();
                    let g = engine
                        .run::<f32>(&sub.plan, None)
                        .unwrap()
                        .observations
                        .convert::<f64>();
                    (c, g)
                }
                Precision::F64 => (
                    Engine::Cpu
                        .run::<f64>(&sub.plan, None)
                        .unwrap()
                        .observations,
                    engine.run::<f64>(&sub.plan, None).unwrap().observations,
                ),
            };
            let tol = if scene.precision == Precision::F32 {
                1e-3
            } else {
                1e-9
            };
            // Cells where a method blows up (finite but huge, e.g. the corners of
            // the stability map) agree in status only.
            let close = |a: f64, b: f64| {
                (a.is_nan() && b.is_nan())
                    || b.abs() > 1e3
                    || (a - b).abs() <= tol * b.abs().max(1.0)
            };
            for i in 0..c.n {
                if c.nonfinite_step[i] != 0 || g.nonfinite_step[i] != 0 {
                    assert!(
                        c.nonfinite_step[i] != 0 && g.nonfinite_step[i] != 0,
                        "{}: status of {i}",
                        path.display()
                    );
                    continue;
                }
                for ((name, a), (_, b)) in g.final_values.iter().zip(&c.final_values) {
                    assert!(
                        close(a[i], b[i]),
                        "{}: final {name}[{i}] gpu {} cpu {}",
                        path.display(),
                        a[i],
                        b[i]
                    );
                }
            }
            for ((name, a), (_, b)) in g
                .trajectory
                .iter()
                .zip(&c.trajectory)
                .chain(g.poincare.iter().zip(&c.poincare))
            {
                for (k, (x, y)) in a.iter().zip(b).enumerate() {
                    assert!(
                        close(*x, *y),
                        "{}: {name}[{k}] gpu {x} cpu {y}",
                        path.display()
                    );
                }
            }
            assert_eq!(g.poincare_count, c.poincare_count, "{}", path.display());
        }
        // And the whole pipeline on the GPU.
        let out = tmp(&format!("{}-gpu", scene.name));
        let opts = RunOptions {
            out: Some(out.clone()),
            task: TaskOptions {
                backend: Some(BackendChoice::Gpu),
                ..TaskOptions::default()
            },
            ..RunOptions::default()
        };
        run_scene(&scene, &opts).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[test]
fn a_failed_run_leaves_no_complete_looking_directory() {
    let scene = Scene::parse(Path::new("t.toml"), "model = \"van_der_pol\"\n[integrator]\ndt = 0.01\nsteps = 10\n[output]\ntrajectory = { every = 1 }\n").unwrap();
    let out = tmp("refused");
    // An output budget of 1 byte: refused before any work, with the estimate.
    let opts = RunOptions {
        out: Some(out.clone()),
        task: TaskOptions {
            backend: Some(BackendChoice::Cpu),
            ..TaskOptions::default()
        },
        max_output_bytes: Some(1),
        ..RunOptions::default()
    };
    let e = format!("{:#}", run_scene(&scene, &opts).err().unwrap());
    assert!(
        e.contains("need about") && e.contains("output.trajectory.every"),
        "{e}"
    );
    assert!(!out.exists());
    // A successful run replaces the directory; no .partial remains.
    let opts = RunOptions {
        out: Some(out.clone()),
        task: TaskOptions {
            backend: Some(BackendChoice::Cpu),
            ..TaskOptions::default()
        },
        ..RunOptions::default()
    };
    run_scene(&scene, &opts).unwrap();
    run_scene(&scene, &opts).unwrap();
    assert!(out.join("summary.json").exists());
    assert!(!out
        .with_file_name(format!(
            "{}.partial",
            out.file_name().unwrap().to_string_lossy()
        ))
        .exists());
    std::fs::remove_dir_all(&out).unwrap();
}
