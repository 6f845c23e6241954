//! Criterion benchmarks `cpu/<model>/<scheme>` and `gpu/<model>/<scheme>`,
//! throughput in trajectory-steps. Kernel compilation and upload happen
//! outside the timed region (the GPU time is the dispatches', by timestamps
//! where the adapter has them). `cargo bench` runs the full suite;
//! `REEB_BENCH_QUICK=1 cargo bench` a short one.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};

use reeb::backend::gpu::GpuContext;
use reeb::backend::Engine;
use reeb::bench::{seconds, SCENARIOS};
use reeb::num::precision::Precision;

fn sizes() -> Vec<usize> {
    if std::env::var_os("REEB_BENCH_QUICK").is_some() {
        vec![10_000]
    } else {
        vec![10_000, 100_000, 1_000_000, 10_000_000]
    }
}

/// 1 thread and all of them.
fn thread_counts() -> Vec<usize> {
    let all = std::thread::available_parallelism().map_or(1, |n| n.get());
    if all > 1 {
        vec![1, all]
    } else {
        vec![1]
    }
}

fn cpu(c: &mut Criterion) {
    let steps = 200;
    for s in SCENARIOS {
        let mut g = c.benchmark_group(format!("cpu/{}", s.label()));
        g.sample_size(10).measurement_time(Duration::from_secs(3));
        for n in sizes() {
            let plan = s.plan(n, steps);
            g.throughput(Throughput::Elements(plan.traj_steps()));
            for p in [Precision::F32, Precision::F64] {
                for threads in thread_counts() {
                    let pool = rayon::ThreadPoolBuilder::new()
                        .num_threads(threads)
                        .build()
                        .expect("thread pool");
                    g.bench_with_input(
                        BenchmarkId::new(format!("{}/{threads}t", p.name()), n),
                        &plan,
                        |b, plan| {
                            b.iter_custom(|iters| {
                                pool.install(|| {
                                    (0..iters)
                                        .map(|_| {
                                            Duration::from_secs_f64(
                                                seconds(&Engine::Cpu, plan, p).expect("cpu run"),
                                            )
                                        })
                                        .sum()
                                })
                            })
                        },
                    );
                }
            }
        }
        g.finish();
    }
}

fn gpu(c: &mut Criterion) {
    let Ok(ctx) = GpuContext::new() else {
        eprintln!("SKIP gpu benches: no adapter");
        return;
    };
    let f64_shaders = ctx.shader_f64;
    let engine = Engine::Gpu(Box::new(ctx));
    let steps = 200;
    for s in SCENARIOS {
        let mut g = c.benchmark_group(format!("gpu/{}", s.label()));
        g.sample_size(10).measurement_time(Duration::from_secs(3));
        for n in sizes() {
            let plan = s.plan(n, steps);
            g.throughput(Throughput::Elements(plan.traj_steps()));
            for p in [Precision::F32, Precision::F64] {
                if p == Precision::F64 && !f64_shaders {
                    continue;
                }
                // Compile and cache the kernel outside the measurement.
                seconds(&engine, &plan, p).expect("gpu run");
                g.bench_with_input(BenchmarkId::new(p.name(), n), &plan, |b, plan| {
                    b.iter_custom(|iters| {
                        (0..iters)
                            .map(|_| {
                                Duration::from_secs_f64(seconds(&engine, plan, p).expect("gpu run"))
                            })
                            .sum()
                    })
                });
            }
        }
        g.finish();
    }
}

criterion_group!(benches, cpu, gpu);
criterion_main!(benches);
