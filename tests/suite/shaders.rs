//! Every model × scheme × precision kernel, with every observer, is valid
//! WGSL (naga, no GPU needed); and the kernels are specialised.

use reeb::backend::gpu::codegen::{generate, ExpForm, Forms};
use reeb::backend::gpu::tuning::Launch;
use reeb::backend::gpu::validate;
use reeb::models::{Model, MODEL_NAMES};
use reeb::num::precision::Precision;
use reeb::plan::observers::{CycleObs, Direction, PoincareObs, Section, TrajectoryObs};
use reeb::plan::scheme::{Scheme, SCHEME_NAMES};
use reeb::plan::{Plan, Problem, Source};
use reeb::verify::indicators::{full_problem, with_indicators};

use crate::common;
use common::{first_var, problem};

#[test]
fn every_kernel_validates() {
    let mut count = 0;
    for model in MODEL_NAMES {
        for scheme in SCHEME_NAMES {
            let Some(base) = problem(model, scheme) else {
                continue;
            };
            let spec = base.model.spec();
            let x = first_var(model);
            let all: Vec<String> = spec.vars.iter().map(|v| v.to_string()).collect();
            // Observer variants: final only; everything (and the optional variable).
            let mut variants = vec![base.clone()];
            let mut full = base.clone();
            if Scheme::by_name(scheme).unwrap().is_splitting() {
                full.observers.final_vars = all.iter().map(|v| v.as_str().into()).collect();
            }
            full.observers.trajectory = Some(TrajectoryObs {
                every: 2,
                vars: vec![x.into(), "t".into()],
            });
            full.observers.poincare = Some(PoincareObs {
                section: Section::Crossing {
                    var: x.into(),
                    value: 0.1,
                    direction: Direction::Both,
                },
                vars: vec![x.into(), "t".into()],
                max_points: 4,
            });
            full.observers.cycle = Some(CycleObs {
                var: x.into(),
                level: 0.0,
                skip: 0.5,
            });
            variants.push(full);
            let mut strobe = base.clone();
            strobe.observers.poincare = Some(PoincareObs {
                section: Section::Stroboscopic {
                    period: 0.25,
                    phase: 0.0,
                },
                vars: vec![x.into()],
                max_points: 4,
            });
            variants.push(strobe.clone());
            strobe.observers.poincare = Some(PoincareObs {
                section: Section::Stroboscopic {
                    period: 0.3333,
                    phase: 0.1,
                },
                vars: vec![x.into()],
                max_points: 4,
            });
            variants.push(strobe);
            for p in variants {
                let plan = Plan::new(&p).unwrap_or_else(|e| panic!("{model} {scheme}: {e}"));
                for precision in [Precision::F32, Precision::F64] {
                    let k = generate(&plan, precision)
                        .unwrap_or_else(|e| panic!("{model} {scheme} {precision}: {e}"));
                    if let Err(e) = validate(&k.source, precision == Precision::F64) {
                        panic!("{model} {scheme} {precision}:\n{e}");
                    }
                    // The source for adapters with 64-bit integers and the
                    // hardware exp, with blocks of steps where the kernel
                    // has no observers.
                    let launch = Launch {
                        finite_block: 4,
                        ..Launch::default()
                    };
                    let forms = Forms {
                        int64: true,
                        exp: ExpForm::Hardware,
                    };
                    let other = k.source_for(&launch, forms);
                    if let Err(e) = validate(&other, precision == Precision::F64) {
                        panic!("{model} {scheme} {precision} (SHADER_INT64, hardware exp, blocks):\n{e}");
                    }
                    count += 1;
                }
            }
        }
    }
    assert!(count > 300, "{count}");
}

/// Every model's kernel with chaos indicators — one exponent, the FLI
/// and MEGNO; the FLI alone, whose sample leaves MEGNO's sums out — is
/// valid WGSL in both precisions, with and without 64-bit integers (the
/// f64 samples' logarithm reads its 2^k·m from the bits with them).
#[test]
fn indicator_kernels_validate() {
    let mut count = 0;
    for model in MODEL_NAMES {
        let Some(p) = full_problem(model, "triple_jump4") else {
            continue;
        };
        let all = with_indicators(p, 1, 1, 0.0, 10, 0.01);
        let mut alone = all.clone();
        alone.observers.lyapunov = None;
        alone.observers.megno = None;
        for p in [all, alone] {
            let plan = Plan::new(&p).unwrap_or_else(|e| panic!("{model}: {e}"));
            for precision in [Precision::F32, Precision::F64] {
                let k = generate(&plan, precision).unwrap_or_else(|e| panic!("{model}: {e}"));
                for int64 in [false, true] {
                    let forms = Forms {
                        int64,
                        exp: ExpForm::Exact,
                    };
                    let source = k.source_for(&Launch::default(), forms);
                    let f64 = precision == Precision::F64;
                    if let Err(e) = validate(&source, f64) {
                        panic!("{model} {precision} int64 {int64}:\n{e}");
                    }
                    count += 1;
                }
            }
        }
    }
    assert!(count >= 40, "{count}");
}

#[test]
fn van_der_pol_qs_kernel_has_no_p_and_no_time() {
    let mut p = Problem::new(Model::VanDerPol, "s2")
        .unwrap()
        .param("epsilon", Source::Const(1.0));
    p.steps = 10;
    let qs = generate(&Plan::new(&p).unwrap(), Precision::F32)
        .unwrap()
        .source;
    let driver = &qs[qs.find("// ---- driver ----").unwrap()..];
    assert!(
        !driver.contains("var p:") && !driver.contains("&p"),
        "{driver}"
    );
    assert!(!driver.contains("van_der_pol_a_p") && !driver.contains("lienard_c_p"));
    assert!(!driver.contains("t = t0"), "autonomous: no time");
    assert!(driver.contains("state[1u * u.cap + i] = s;") && !driver.contains("state[2u"));
    p.observers.final_vars = vec!["q".into(), "s".into(), "p".into()];
    let qsp = generate(&Plan::new(&p).unwrap(), Precision::F32)
        .unwrap()
        .source;
    let driver_p = &qsp[qsp.find("// ---- driver ----").unwrap()..];
    assert!(driver_p.contains("van_der_pol_a_p(q, s, &p, tau, epsilon)"));
    assert!(driver_p.contains("state[2u * u.cap + i] = p;"));
    // Per-thread state: 2 integrated variables instead of 3.
    assert!(driver.matches("var ").count() < driver_p.matches("var ").count());
}

/// The host's `Uniforms` (gpu/run.rs) and the driver's (driver.wgsl) have
/// the same size, as naga lays the WGSL struct out.
#[test]
fn uniforms_match_the_driver() {
    let plan = Plan::new(&problem("van_der_pol", "s2").unwrap()).unwrap();
    let kernel = generate(&plan, Precision::F32).unwrap();
    let module = naga::front::wgsl::parse_str(&kernel.source).unwrap();
    let (_, ty) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some("Uniforms"))
        .expect("driver declares Uniforms");
    let naga::TypeInner::Struct { span, .. } = ty.inner else {
        panic!("Uniforms is not a struct");
    };
    assert_eq!(span as usize, reeb::backend::gpu::run::UNIFORMS_BYTES);
}
