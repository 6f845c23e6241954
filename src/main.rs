//! The `reeb` command line.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use reeb::real::Precision;
use reeb::verify::{run_all, CpuEngine, Engine, GpuEngine};

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
    /// Run the oracles of SPEC §4 and measure the convergence order of every scheme.
    Verify {
        /// Backend to verify.
        #[arg(long, default_value = "cpu", value_parser = ["cpu", "gpu"])]
        backend: String,
        /// Working precision.
        #[arg(long, default_value = "f64")]
        precision: Precision,
    },
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match cli.command {
        Command::Verify { backend, precision } => {
            if backend == "gpu" {
                match reeb::backend::gpu::GpuContext::new() {
                    Ok(ctx) => verify(&GpuEngine {
                        ctx: &ctx,
                        precision,
                    }),
                    Err(e) => {
                        eprintln!("error: {e}");
                        ExitCode::FAILURE
                    }
                }
            } else {
                verify(&CpuEngine(precision))
            }
        }
    }
}

fn verify(engine: &dyn Engine) -> ExitCode {
    println!(
        "reeb verify: backend {}, precision {}",
        engine.describe(),
        engine.precision()
    );
    println!(
        "{:<4} {:<92} {:>16} {:>16} {:>12}",
        "", "check", "expected", "measured", "tolerance"
    );
    let rows = run_all(engine, |c| {
        println!(
            "{:<4} {:<92} {:>16} {:>16} {:>12}",
            if c.pass { "pass" } else { "FAIL" },
            c.name,
            c.expected,
            c.measured,
            c.tolerance
        );
    });
    let failed = rows.iter().filter(|c| !c.pass).count();
    println!("{} passed, {} failed", rows.len() - failed, failed);
    if failed == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
