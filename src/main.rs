//! The `reeb` command line.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};

use reeb::backend::gpu::list_adapters;
use reeb::backend::Engine;
use reeb::num::precision::Precision;
use reeb::output::run::{gates, run_scene, Gated, RunOptions, TaskOptions};
use reeb::output::stream::Watch;
use reeb::scene::{BackendChoice, Scene};
use reeb::verify::{run_all, Target};

#[derive(Parser)]
#[command(
    name = "reeb",
    version,
    about = "Contact Hamiltonian splitting integrators for large ensembles, on the CPU and the GPU"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Integrate a scene: arrays (.npy), summary.json and pictures in one directory.
    Run {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Quick look: at most 4 values per axis and 2000 steps per plan, into runs/<name>-preview.
        #[arg(long)]
        preview: bool,
        #[command(flatten)]
        opts: RunOptions,
    },
    /// Run a scene on a Slurm cluster: a job array of N shards (each
    /// `reeb run --shard K/N --resume`) and a merge job after it.
    Slurm {
        /// The scene file (TOML).
        scene: PathBuf,
        /// Number of shards (array tasks).
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..=100_000))]
        shards: u64,
        /// Output directory (default: runs/<scene name>); the scripts and logs go to DIR.slurm.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Slurm partition of the jobs.
        #[arg(long)]
        partition: Option<String>,
        /// GPUs per array task.
        #[arg(long)]
        gpus_per_task: Option<u32>,
        /// Wall-time limit per task (Slurm's format, e.g. 2:00:00).
        #[arg(long)]
        time: Option<String>,
        /// Write the batch scripts without submitting them.
        #[arg(long)]
        dry_run: bool,
        /// What every task runs with (as `reeb run`'s flags).
        #[command(flatten)]
        task: TaskOptions,
    },
    /// Finish a run integrated in shards (`reeb run --shard K/N`): check that
    /// every shard finished, then write summary.json and the pictures.
    Merge {
        /// The output directory the shards wrote (its DIR.partial).
        dir: PathBuf,
        /// Replace DIR even when it holds files reeb did not write (they are deleted).
        #[arg(long)]
        force: bool,
    },
    /// Reports: work-precision (error against run time per scheme, backend,
    /// precision and step) or stability (accurate / distorted / diverged over a 2-D grid).
    Report {
        #[command(subcommand)]
        kind: ReportKind,
    },
    /// Check a scene file without running it: errors refuse it; warnings
    /// (on stderr) say what is merely surprising.
    Check {
        scene: PathBuf,
        /// Check for this precision (f32 or f64) instead of the scene's.
        #[arg(long)]
        precision: Option<Precision>,
        /// Check that `reeb run` could write this directory (default: runs/<scene name>).
        #[arg(long)]
        out: Option<PathBuf>,
        /// Check as `reeb run --force` would run.
        #[arg(long)]
        force: bool,
    },
    /// List GPU adapters, their type, limits, and whether f64 and timestamps are available.
    Info,
    /// Measure trajectory-steps per second on this machine (median of repeats).
    Bench {
        /// Backends: cpu, gpu (default: cpu, and gpu when an adapter exists).
        #[arg(long, value_delimiter = ',')]
        backend: Vec<String>,
        /// Scenarios (default: all): van_der_pol/s2, van_der_pol/s2_with_p, van_der_pol/yoshida6a, spin_orbit/s2, kepler/s2, lienard_formula/s2.
        #[arg(long, value_delimiter = ',')]
        scenario: Vec<String>,
        /// Precisions.
        #[arg(long, value_delimiter = ',', default_value = "f32,f64")]
        precision: Vec<Precision>,
        /// Ensemble sizes (default: 100000,1000000).
        #[arg(long, value_delimiter = ',')]
        n: Vec<usize>,
        /// Steps per run (default: 1000; with --indicators, each cost scene's own).
        #[arg(long)]
        steps: Option<u64>,
        /// CPU thread counts (default: 1 and all).
        #[arg(long, value_delimiter = ',')]
        threads: Vec<usize>,
        /// Repeats per measurement (the median is reported).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Also write the rows as JSON lines to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Instead of throughput: what each chaos indicator costs, as a multiple of the
        /// same scene's plain run (van der Pol and spin–orbit cost scenes, in
        /// alternating pairs; --repeats pairs, the median ratio).
        #[arg(long)]
        indicators: bool,
        /// With --indicators: the indicators sampled every N steps, as a scene's
        /// `every = N` (default 1, the setting the goals are stated for).
        #[arg(long, value_name = "N")]
        every: Option<u64>,
    },
    /// Check and measure the GPU backend on this machine: the adapters, `verify` on the
    /// GPU in f32 and f64, the CPU–GPU agreement of every model, throughput on both
    /// backends; a table, and one JSON file. Exit status 1 when a check fails or no adapter exists.
    Doctor {
        /// The JSON report (replaced only if it is an earlier `reeb doctor` report).
        #[arg(long, default_value = "reeb-doctor.json")]
        out: PathBuf,
        /// The adapter to check, by its index in `reeb info` (default: the one `--backend gpu` takes).
        #[arg(long)]
        adapter: Option<usize>,
        /// Ensemble sizes of the throughput rows (default: 1000000,10000000; 10000,100000 on a software adapter).
        #[arg(long, value_delimiter = ',')]
        n: Vec<usize>,
        /// Skip `reeb verify` (minutes on a software adapter).
        #[arg(long)]
        skip_verify: bool,
    },
    /// Measure again, and cache, the GPU launch of each plan shape (model and
    /// precision) on an adapter: workgroup size, trajectories per invocation,
    /// time per dispatch, with the CPU's rate beside it (what `--backend auto`
    /// weighs). Without a scene: the models of `reeb bench`'s scenarios.
    Tune {
        /// A scene whose plans to tune.
        scene: Option<PathBuf>,
        /// The adapter, by its index in `reeb info` (default: the one `--backend gpu` takes).
        #[arg(long)]
        adapter: Option<usize>,
        /// Precisions.
        #[arg(long, value_delimiter = ',', default_value = "f32,f64")]
        precision: Vec<Precision>,
    },
    /// Run the oracles (each model's exact solutions and known values) and
    /// measure the convergence order of every scheme; with a scene, measure
    /// its scheme's order (and S2's, Yoshida 6A's) on it against DOP853, and
    /// the CPU–GPU agreement on it.
    Verify {
        /// A scene to verify (e.g. a formula model) instead of the built-in checks.
        scene: Option<PathBuf>,
        /// Backend to verify.
        #[arg(long, default_value = "cpu", value_parser = ["cpu", "gpu"])]
        backend: String,
        /// Working precision.
        #[arg(long, default_value = "f64")]
        precision: Precision,
    },
}

#[derive(Subcommand)]
enum ReportKind {
    /// For every scheme, backend and precision of the scene's [report] table and every dt of its axis: error and time.
    WorkPrecision(ReportArgs),
    /// Classify every cell of a 2-D grid as accurate, distorted or diverged.
    Stability(ReportArgs),
}

#[derive(clap::Args)]
struct ReportArgs {
    scene: PathBuf,
    /// Output directory (default: runs/<scene name>-<report>, e.g. runs/vdp-stability).
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long)]
    backend: Option<BackendChoice>,
    #[arg(long)]
    precision: Option<Precision>,
    /// Replace the output directory even when it holds files reeb did not write (they are deleted).
    #[arg(long)]
    force: bool,
}

fn main() -> ExitCode {
    // Output piped into `head` and the like: end quietly, as Unix tools do,
    // instead of panicking on the broken pipe.
    #[cfg(unix)]
    // SAFETY: restoring the default action of a signal before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    if let Some(e) = reeb::backend::cpu::kernels::isa_cap_error() {
        eprintln!("error: {e}");
        return ExitCode::FAILURE;
    }
    let result = match cli.command {
        Command::Run {
            scene,
            preview,
            opts,
        } => run(scene, preview, opts),
        Command::Merge { dir, force } => merge(&dir, force),
        Command::Slurm {
            scene,
            shards,
            out,
            partition,
            gpus_per_task,
            time,
            dry_run,
            task,
        } => {
            let opts = reeb::output::slurm::SlurmOptions {
                shards: usize::try_from(shards).unwrap_or(usize::MAX),
                out: PathBuf::new(),
                partition,
                gpus_per_task,
                time,
                dry_run,
                run_args: task.to_args(),
            };
            slurm(&scene, out, task.precision, opts)
        }
        Command::Check {
            scene,
            precision,
            out,
            force,
        } => check(scene, precision, out, force),
        Command::Info => info(),
        Command::Report { kind } => report(kind),
        Command::Bench {
            backend,
            scenario,
            precision,
            n,
            steps,
            threads,
            repeats,
            json,
            indicators,
            every,
        } => {
            if indicators {
                bench_indicators(
                    backend, scenario, precision, n, steps, threads, repeats, json, every,
                )
            } else if every.is_some() {
                Err(anyhow::anyhow!("--every: only with --indicators"))
            } else {
                bench(
                    backend, scenario, precision, n, steps, threads, repeats, json,
                )
            }
        }
        Command::Doctor {
            out,
            adapter,
            n,
            skip_verify,
        } => doctor(out, adapter, n, skip_verify),
        Command::Tune {
            scene,
            adapter,
            precision,
        } => tune(scene, adapter, precision),
        Command::Verify {
            scene,
            backend,
            precision,
        } => {
            let engine = if backend == "gpu" {
                Engine::gpu(None)
            } else {
                Ok(Engine::Cpu)
            };
            engine
                .map_err(anyhow::Error::from)
                .and_then(|engine| verify(&Target { engine, precision }, scene.as_deref()))
        }
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(scene: PathBuf, preview: bool, mut opts: RunOptions) -> Result<ExitCode> {
    opts.started = Some(std::time::Instant::now());
    let mut scene = Scene::load(&scene)?;
    if preview {
        scene = scene.preview(4, 2000);
    }
    let watch = Arc::new(Watch::default());
    interrupt::forward_to(watch.stop.clone());
    opts.progress = true;
    opts.watch = Some(watch);
    let report = match run_scene(&scene, &opts) {
        Ok(report) => report,
        Err(e) => match interrupt::received() {
            Some(signal) => {
                eprintln!("error: {e:#}");
                eprintln!(
                    "interrupted by {}; to continue where it stopped:\n  {}",
                    interrupt::name(signal),
                    interrupt::resume_command()
                );
                return Ok(ExitCode::from(128 + signal as u8));
            }
            None => return Err(e),
        },
    };
    println!("{}", report.line);
    Ok(ExitCode::SUCCESS)
}

/// Ctrl-C and SIGTERM (`kill`, a batch system's time limit) during `reeb
/// run`: the run is asked to stop where it can keep its work (a checkpoint
/// of the chunk in progress), and says how to continue. A second one ends
/// the process at once.
mod interrupt {
    use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
    use std::sync::Arc;
    use std::time::Duration;

    static RECEIVED: AtomicI32 = AtomicI32::new(0);

    extern "C" fn on_signal(signal: libc::c_int) {
        RECEIVED.store(signal, Ordering::SeqCst);
        // SAFETY: signal() is async-signal-safe; the next one kills.
        unsafe {
            libc::signal(signal, libc::SIG_DFL);
        }
    }

    /// Installs the handlers; a thread sets `stop` once a signal came.
    pub fn forward_to(stop: Arc<AtomicBool>) {
        let handler = on_signal as extern "C" fn(libc::c_int) as libc::sighandler_t;
        // SAFETY: the handler only stores to an atomic and calls signal().
        unsafe {
            libc::signal(libc::SIGINT, handler);
            libc::signal(libc::SIGTERM, handler);
        }
        std::thread::spawn(move || loop {
            if received().is_some() {
                stop.store(true, Ordering::SeqCst);
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        });
    }

    /// The signal received, if one was.
    pub fn received() -> Option<i32> {
        Some(RECEIVED.load(Ordering::SeqCst)).filter(|s| *s != 0)
    }

    pub fn name(signal: i32) -> &'static str {
        match signal {
            libc::SIGINT => "SIGINT (Ctrl-C)",
            libc::SIGTERM => "SIGTERM",
            _ => "a signal",
        }
    }

    /// This command line with `--resume`, as a shell reads it.
    pub fn resume_command() -> String {
        let mut args: Vec<String> = std::env::args().collect();
        if !args.iter().any(|a| a == "--resume") {
            args.push("--resume".into());
        }
        args.iter()
            .map(|a| shell_word(a))
            .collect::<Vec<_>>()
            .join(" ")
    }

    fn shell_word(a: &str) -> String {
        let plain = !a.is_empty()
            && a.chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_./=:,+@%".contains(c));
        match plain {
            true => a.to_string(),
            false => format!("'{}'", a.replace('\'', r"'\''")),
        }
    }
}

/// `reeb slurm`: the scene checked as `reeb check` does, then its jobs.
fn slurm(
    scene: &Path,
    out: Option<PathBuf>,
    precision: Option<Precision>,
    mut opts: reeb::output::slurm::SlurmOptions,
) -> Result<ExitCode> {
    let s = Scene::load(scene)?;
    let Gated { out, .. } = gates(&s, precision.unwrap_or(s.precision), out.as_deref(), None)?;
    reeb::output::directory::check(&out, &[&s.path], false)?;
    opts.out = out;
    let jobs = reeb::output::slurm::submit(scene, &s.name, &opts)?;
    println!("{}", jobs.line);
    Ok(ExitCode::SUCCESS)
}

/// `reeb merge DIR`.
fn merge(dir: &Path, force: bool) -> Result<ExitCode> {
    let report = reeb::output::run::merge(dir, force)?;
    println!("{}", report.line);
    Ok(ExitCode::SUCCESS)
}

/// `reeb check`: every gate of `reeb run` (the scene's names and sizes
/// in `Scene::load`, the precision's checks, the outputs' size against the
/// same limit, the output directory), without running or writing anything.
fn check(
    scene: PathBuf,
    precision: Option<Precision>,
    out: Option<PathBuf>,
    force: bool,
) -> Result<ExitCode> {
    let s = Scene::load(&scene)?;
    let precision = precision.unwrap_or(s.precision);
    let Gated {
        warnings,
        subs: runs,
        estimate,
        out,
    } = gates(&s, precision, out.as_deref(), None)?;
    reeb::output::directory::check(&out, &[&s.path], force)?;
    println!(
        "{}: ok: model {}, scheme {}, {precision}, {} trajectories over {} axes, {} plan(s), outputs about {} into {}{}",
        s.path.display(),
        s.model.name(),
        s.scheme,
        s.ensemble_size(),
        s.axes.len(),
        runs.len(),
        reeb::plan::size::bytes(estimate.bytes),
        out.display(),
        match warnings.len() {
            0 => String::new(),
            1 => ", 1 warning".into(),
            n => format!(", {n} warnings"),
        }
    );
    Ok(ExitCode::SUCCESS)
}

#[allow(clippy::too_many_arguments)]
fn bench(
    backends: Vec<String>,
    scenarios: Vec<String>,
    precisions: Vec<Precision>,
    sizes: Vec<usize>,
    steps: Option<u64>,
    threads: Vec<usize>,
    repeats: usize,
    json: Option<PathBuf>,
) -> Result<ExitCode> {
    use reeb::bench::{BenchOptions, Scenario};
    let sizes = match sizes.is_empty() {
        true => vec![100_000, 1_000_000],
        false => sizes,
    };
    let steps = steps.unwrap_or(1000);
    check_bench_args(&sizes, steps, &threads, repeats)?;
    let scenarios = scenarios
        .iter()
        .map(|s| {
            Scenario::by_label(s)
                .ok_or_else(|| anyhow::anyhow!("--scenario: unknown scenario `{s}`"))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut out = json.map(std::fs::File::create).transpose()?;
    println!(
        "reeb {} bench: {steps} steps per run (a hardware GPU's runs lengthened to {} s, so that its clocks rise), median of {repeats}",
        env!("CARGO_PKG_VERSION"),
        reeb::bench::GPU_RUN_SECONDS
    );
    println!(
        "{:<40} {:<24} {:>9} {:>10} {:>8} {:>8} {:>16} {:>16}",
        "backend", "scenario", "precision", "n", "steps", "threads", "traj-steps/s", "whole run"
    );
    let opts = BenchOptions {
        backends,
        scenarios,
        precisions,
        sizes,
        steps,
        threads,
        repeats,
    };
    let mut written = Ok(());
    reeb::bench::run(&opts, |row| {
        if written.is_ok() {
            written = print_bench_row(row, out.as_mut());
        }
    })
    .map_err(anyhow::Error::msg)?;
    written?;
    Ok(ExitCode::SUCCESS)
}

/// `reeb bench --indicators`: each indicator's cost on each cost scene,
/// backend and precision, a row as it is measured; the indicators sampled
/// every `every` steps (default 1).
#[allow(clippy::too_many_arguments)]
fn bench_indicators(
    backends: Vec<String>,
    scenarios: Vec<String>,
    precisions: Vec<Precision>,
    sizes: Vec<usize>,
    steps: Option<u64>,
    threads: Vec<usize>,
    repeats: usize,
    json: Option<PathBuf>,
    every: Option<u64>,
) -> Result<ExitCode> {
    use reeb::bench::indicators::{cost, COST_SCENES, INDICATORS};
    let fixed =
        "with --indicators: the cost scenes' grids are fixed, and the CPU takes every thread";
    for (flag, given) in [
        ("--n", !sizes.is_empty()),
        ("--scenario", !scenarios.is_empty()),
        ("--threads", !threads.is_empty()),
    ] {
        if given {
            anyhow::bail!("{flag}: not used {fixed}");
        }
    }
    check_bench_args(&[], steps.unwrap_or(1), &[], repeats)?;
    let every = every.unwrap_or(1);
    for scene in COST_SCENES {
        let run_steps = steps.unwrap_or(scene.steps());
        if every == 0 || every > run_steps {
            anyhow::bail!(
                "--every: {every} is not between 1 and the {run_steps} steps of {}",
                scene.label()
            );
        }
    }
    let engines = reeb::bench::engines(&backends).map_err(anyhow::Error::msg)?;
    let mut out = json
        .map(|p| std::fs::File::create(&p).with_context(|| format!("--json {}", p.display())))
        .transpose()?;
    println!(
        "reeb {} bench --indicators: each run against its plain run, median of {repeats} alternating pairs{}",
        env!("CARGO_PKG_VERSION"),
        match every {
            1 => String::new(),
            m => format!(", the indicators sampled every {m} steps"),
        }
    );
    println!(
        "{:<40} {:<26} {:>9} {:<38} {:>8} {:>9} {:>9} {:>7} {:>5}",
        "backend", "scene", "precision", "indicator", "steps", "plain s", "with s", "ratio", "goal"
    );
    for (name, engine) in engines.each() {
        for scene in COST_SCENES {
            for &p in precisions.iter().filter(|&&p| engine.runs(p)) {
                for ind in INDICATORS {
                    let run_steps = steps.unwrap_or(scene.steps());
                    let r = cost(engine, &name, scene, ind, every, p, run_steps, repeats)
                        .map_err(|e| anyhow::anyhow!("{name} {}: {e}", scene.label()))?;
                    print_cost_row(&r, out.as_mut())?;
                }
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// One line of `reeb bench --indicators`, and its JSON line.
fn print_cost_row(
    r: &reeb::bench::indicators::CostRow,
    json: Option<&mut std::fs::File>,
) -> Result<()> {
    use std::io::Write;
    let verdict = if r.ratio <= r.goal { "" } else { " over" };
    println!(
        "{:<40} {:<26} {:>9} {:<38} {:>8} {:>9.3} {:>9.3} {:>7.2} {:>5}{verdict}",
        r.backend,
        r.scene,
        r.precision.name(),
        r.indicator,
        r.steps,
        r.plain_s,
        r.indicator_s,
        r.ratio,
        r.goal
    );
    if let Some(f) = json {
        writeln!(f, "{}", serde_json::to_string(r)?)?;
    }
    Ok(())
}

/// `reeb doctor`: the checks and measurements of `reeb::doctor`, a table on
/// stdout, the report in `out`.
fn doctor(
    out: PathBuf,
    adapter: Option<usize>,
    n: Vec<usize>,
    skip_verify: bool,
) -> Result<ExitCode> {
    if n.contains(&0) {
        anyhow::bail!("--n: ensemble sizes must be at least 1");
    }
    check_doctor_out(&out)?;
    let opts = reeb::doctor::DoctorOptions {
        adapter,
        sizes: (!n.is_empty()).then_some(n),
        skip_verify,
    };
    let report = reeb::doctor::run(&opts, |line| eprintln!("doctor: {line}"));
    print!("{}", report.table());
    let tmp = out.with_extension("json.partial");
    std::fs::write(&tmp, serde_json::to_string_pretty(&report)? + "\n")
        .and_then(|_| std::fs::rename(&tmp, &out))
        .with_context(|| format!("--out {}", out.display()))?;
    println!("report: {}", out.display());
    Ok(if report.healthy() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

/// `reeb doctor --out FILE` replaces only an earlier report, and its folder
/// must exist: both known before minutes of measurements.
fn check_doctor_out(out: &Path) -> Result<()> {
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty());
    if let Some(p) = parent.filter(|p| !p.is_dir()) {
        anyhow::bail!(
            "--out {}: the folder {} does not exist",
            out.display(),
            p.display()
        );
    }
    if out.exists() {
        let earlier = std::fs::read_to_string(out)
            .ok()
            .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
            .is_some_and(|v| v.get("adapters").is_some() && v.get("bench").is_some());
        if !earlier {
            anyhow::bail!(
                "--out {}: the file exists and is not a `reeb doctor` report; name another file",
                out.display()
            );
        }
    }
    Ok(())
}

/// Sizes, steps, threads and repeats a benchmark can run (each ≥ 1; the
/// largest ensemble's final values fit in memory).
fn check_bench_args(sizes: &[usize], steps: u64, threads: &[usize], repeats: usize) -> Result<()> {
    if let Some(n) = sizes.iter().find(|n| **n == 0) {
        anyhow::bail!("--n: an ensemble needs at least 1 trajectory (got {n})");
    }
    if steps == 0 || steps >= reeb::plan::MAX_STEPS {
        anyhow::bail!(
            "--steps: {steps} is not between 1 and {}",
            reeb::plan::MAX_STEPS - 1
        );
    }
    if threads.contains(&0) {
        anyhow::bail!("--threads: a thread count must be at least 1");
    }
    // More threads than cores only measures the scheduler, and a pool of
    // 10⁵ threads takes minutes to start (found by tests/suite/cli_fuzz.rs).
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let most = 4 * cores;
    if let Some(t) = threads.iter().find(|t| **t > most) {
        anyhow::bail!(
            "--threads: {t} threads on {cores} cores; at most {most} (4 per core) are measured"
        );
    }
    if repeats == 0 {
        anyhow::bail!("--repeats: must be at least 1");
    }
    // Two f64 final values per trajectory, and the plan's inputs: 32 bytes each.
    let largest = sizes.iter().copied().max().unwrap_or(0) as u64;
    let need = largest.saturating_mul(32);
    if let Some(avail) = reeb::plan::size::available_memory() {
        if need > avail / 2 {
            anyhow::bail!(
                "--n: {largest} trajectories need about {} GiB and {} GiB is available; use a smaller --n",
                need >> 30,
                avail >> 30
            );
        }
    }
    Ok(())
}

/// One line of `reeb bench`, and its JSON line.
fn print_bench_row(r: &reeb::bench::Row, json: Option<&mut std::fs::File>) -> Result<()> {
    use std::io::Write;
    let th = match r.threads {
        0 => "-".to_string(),
        t => t.to_string(),
    };
    let whole = r
        .whole_run_traj_steps_per_s
        .map_or("-".to_string(), |w| format!("{w:.4e}"));
    println!(
        "{:<40} {:<24} {:>9} {:>10} {:>8} {:>8} {:>16.4e} {whole:>16}",
        r.backend, r.scenario, r.precision, r.n, r.steps, th, r.traj_steps_per_s
    );
    if let Some(f) = json {
        writeln!(
            f,
            "{}",
            serde_json::json!({"backend": r.backend, "scenario": r.scenario, "precision": r.precision.name(), "n": r.n, "steps": r.steps, "threads": r.threads, "traj_steps_per_s": r.traj_steps_per_s, "whole_run_traj_steps_per_s": r.whole_run_traj_steps_per_s})
        )?;
    }
    Ok(())
}

fn report(kind: ReportKind) -> Result<ExitCode> {
    use reeb::report::{stability, work_precision, ReportOptions};
    let (args, make): (_, fn(&Scene, &ReportOptions) -> Result<PathBuf>) = match kind {
        ReportKind::WorkPrecision(args) => (args, work_precision),
        ReportKind::Stability(args) => (args, stability),
    };
    let scene = Scene::load(&args.scene)?;
    let written = make(
        &scene,
        &ReportOptions {
            out: args.out,
            backend: args.backend,
            precision: args.precision,
            force: args.force,
            stop: None,
        },
    )?;
    println!("{}", written.display());
    Ok(ExitCode::SUCCESS)
}

fn info() -> Result<ExitCode> {
    let isa = reeb::backend::cpu::isa().label();
    println!(
        "reeb {}; CPU backend: {} threads (rayon), {isa} kernels",
        env!("CARGO_PKG_VERSION"),
        reeb::backend::cpu::threads()
    );
    let adapters = list_adapters();
    if adapters.is_empty() {
        println!("no GPU adapter (what to do: the `--backend gpu` line below)");
    }
    for (k, a) in adapters.iter().enumerate() {
        println!("adapter: {}", a.name);
        println!(
            "  index {k} (--adapter {k}), backend {}, type {}, driver {}",
            a.backend, a.device_type, a.driver
        );
        println!(
            "  f64 shaders: {}, 64-bit integers: {}, timestamp queries: {}",
            if a.shader_f64 { "yes" } else { "no" },
            if a.shader_int64 { "yes" } else { "no" },
            if a.timestamps { "yes" } else { "no" }
        );
        println!(
            "  f32 exp: {} (REEB_GPU_EXP=exact or hardware to choose)",
            match a.exp_f32 {
                reeb::backend::gpu::codegen::ExpForm::Exact =>
                    "reeb's polynomial, the CPU's function",
                reeb::backend::gpu::codegen::ExpForm::Hardware =>
                    "the adapter's exp2 on a split argument, where it measures within 4 ULP as a device opens",
            }
        );
        println!(
            "  limits: storage binding {} MiB, buffer {} MiB, {} workgroups per dimension, {} storage buffers per stage",
            a.max_storage_buffer_binding_size >> 20,
            a.max_buffer_size >> 20,
            a.max_compute_workgroups_per_dimension,
            a.max_storage_buffers_per_shader_stage
        );
    }
    print_tuning(&adapters);
    // Opened as a run opens it: its exp2 form kept only where it measures
    // accurate.
    match Engine::gpu(None) {
        Ok(Engine::Cpu) => {}
        Ok(Engine::Gpu(ctx)) => println!(
            "--backend gpu uses: {}; --backend auto uses: {}",
            ctx.describe(),
            if reeb::backend::gpu::is_software(&ctx.info) {
                "the CPU (the adapter is a software one)"
            } else {
                "the faster of the GPU and the CPU for each plan shape and precision, as the tuning measured them"
            }
        ),
        Err(e) => println!("--backend gpu: unavailable ({e}); --backend auto uses the CPU"),
    }
    Ok(ExitCode::SUCCESS)
}

/// `reeb tune`: a row per plan shape probed again, and where they are kept.
fn tune(
    scene: Option<PathBuf>,
    adapter: Option<usize>,
    precisions: Vec<Precision>,
) -> Result<ExitCode> {
    use reeb::backend::gpu::tuning;
    let engine = Engine::gpu(adapter).context("reeb tune measures a GPU adapter")?;
    let scene = scene.as_deref().map(Scene::load).transpose()?;
    println!(
        "reeb {} tune: {}",
        env!("CARGO_PKG_VERSION"),
        engine.describe()
    );
    println!(
        "{:<28} {:<60} {:>14} {:>14} {:>8} {:>10}",
        "shape", "launch", "GPU steps/s", "CPU steps/s", "probe s", "compile s"
    );
    let rows = reeb::bench::tune(&engine, scene.as_ref(), &precisions, |t| {
        println!(
            "{:<28} {:<60} {:>14.4e} {:>14.4e} {:>8.2} {:>10.2}",
            t.shape,
            t.tuned.launch.describe(),
            t.tuned.gpu_rate,
            t.tuned.cpu_rate,
            t.tuned.probe_seconds,
            t.tuned.compile_seconds
        );
    })?;
    if rows.is_empty() {
        anyhow::bail!("nothing to tune: the adapter runs none of the precisions asked for");
    }
    if let Some(dir) = tuning::cache_dir() {
        println!("cached in {}", dir.join(tuning::CACHE_FILE).display());
    }
    let env = tuning::Overrides::from_env().map_err(anyhow::Error::msg)?;
    if env != tuning::Overrides::default() {
        println!(
            "note: the environment overrides these choices: {}",
            env.describe()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// `reeb info`'s tuning lines: the cached launches of each adapter, and
/// the environment's overrides.
fn print_tuning(adapters: &[reeb::backend::gpu::AdapterSummary]) {
    use reeb::backend::gpu::tuning::{cache_dir, Cache, Overrides, CACHE_FILE};
    let cache = Cache::load();
    let file = cache_dir().map_or("(no cache directory)".into(), |d| {
        d.join(CACHE_FILE).display().to_string()
    });
    println!("GPU tuning (cache: {file}):");
    for (k, a) in adapters.iter().enumerate() {
        let tuned = cache.tuned.get(&a.tuning_key);
        if tuned.is_none_or(|t| t.is_empty()) {
            println!("  adapter {k}: not tuned yet (the first run of a plan shape probes it, about 1 s; or `reeb tune --adapter {k}`)");
        }
        for (shape, t) in tuned.into_iter().flatten() {
            println!(
                "  adapter {k}, {shape}: {}; GPU {:.3e}, CPU {:.3e} trajectory-steps/s; probe {:.2} s, of which {:.2} s compiling",
                t.launch.describe(),
                t.gpu_rate,
                t.cpu_rate,
                t.probe_seconds,
                t.compile_seconds
            );
        }
    }
    match Overrides::from_env() {
        Ok(o) if o == Overrides::default() => {}
        Ok(o) => println!("  overridden by the environment: {}", o.describe()),
        Err(e) => println!("  error in the environment: {e}"),
    }
}

fn verify(engine: &Target, scene: Option<&Path>) -> anyhow::Result<ExitCode> {
    let scene = scene.map(Scene::load).transpose()?;
    println!(
        "reeb verify{}: backend {}, precision {}",
        scene
            .as_ref()
            .map(|s| format!(" {}", s.path.display()))
            .unwrap_or_default(),
        engine.describe(),
        engine.precision
    );
    println!(
        "{:<4} {:<92} {:>16} {:>16} {:>12}",
        "", "check", "expected", "measured", "tolerance"
    );
    let print = |c: &reeb::verify::Check| {
        println!(
            "{:<4} {:<92} {:>16} {:>16} {:>12}",
            if c.pass { "pass" } else { "FAIL" },
            c.name,
            c.expected,
            c.measured,
            c.tolerance
        );
    };
    let rows = match &scene {
        Some(s) => reeb::verify_scene::run_scene(s, engine, print),
        None => run_all(engine, print),
    };
    let failed = rows.iter().filter(|c| !c.pass).count();
    println!("{} passed, {} failed", rows.len() - failed, failed);
    Ok(if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}
