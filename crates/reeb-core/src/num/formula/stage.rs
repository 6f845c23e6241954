//! A program split by what its values vary with, so that work is done as
//! rarely as it may be: values that no step changes are computed once per
//! block (`fixed`), values the whole ensemble shares that change each step
//! (functions of the time when `t0` and `dt` are not axes) once per step
//! for all lanes (`uniform`), and only the rest per lane and step (`lane`).
//!
//! The three parts read one index space of inputs: the program's own inputs
//! `0..n`, then the outputs of `fixed` (`n..n+F`), then those of `uniform`
//! (`n+F..n+F+U`). Every value is computed by the same operations as in the
//! unsplit program, so the results are bitwise the same.

use super::lower::{Instr, Lowered, Operand};

/// How an input varies: from lane to lane, from step to step.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Vary {
    pub lane: bool,
    pub step: bool,
}

/// A program in three parts; see the module documentation.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Staged {
    pub fixed: Lowered,
    pub uniform: Lowered,
    pub lane: Lowered,
    /// The program's inputs (`n`).
    pub inputs: u32,
}

impl Staged {
    /// Does input `k` (of the shared index space) hold one value for every
    /// lane when `lane` runs?
    pub fn scalar_in_lane(&self, k: u32, vary: &[Vary]) -> bool {
        match vary.get(k as usize) {
            Some(v) => !v.lane,
            None => k >= self.inputs + self.fixed.outputs.len() as u32,
        }
    }
}

/// Which part computes an instruction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Part {
    Fixed,
    Uniform,
    Lane,
}

fn part(v: Vary) -> Part {
    match (v.lane, v.step) {
        (_, false) => Part::Fixed,
        (false, true) => Part::Uniform,
        (true, true) => Part::Lane,
    }
}

/// Each instruction's part, and whether its value is read by another part
/// (or is a program output computed outside the lane part).
fn classify(l: &Lowered, vary: &[Vary]) -> (Vec<Part>, Vec<bool>) {
    let none = Vary {
        lane: false,
        step: false,
    };
    // What each instruction's value varies with.
    let mut of: Vec<Vary> = Vec::with_capacity(l.instrs.len());
    let vary_of = |of: &[Vary], o: Operand| match o {
        Operand::Val(k) => of[k as usize],
        Operand::Input(k) => vary[k as usize],
        Operand::Const(_) => none,
    };
    for i in &l.instrs {
        let (a, b) = (vary_of(&of, i.a), vary_of(&of, i.b));
        of.push(Vary {
            lane: a.lane || b.lane,
            step: a.step || b.step,
        });
    }
    let parts: Vec<Part> = of.iter().map(|v| part(*v)).collect();
    let mut exported = vec![false; l.instrs.len()];
    for (k, i) in l.instrs.iter().enumerate() {
        for o in [i.a, i.b] {
            if let Operand::Val(v) = o {
                exported[v as usize] |= parts[v as usize] != parts[k];
            }
        }
    }
    for o in &l.outputs {
        if let Operand::Val(v) = *o {
            exported[v as usize] |= parts[v as usize] != Part::Lane;
        }
    }
    (parts, exported)
}

/// Splits `l`, whose input `k` varies as `vary[k]`.
pub fn split(l: &Lowered, vary: &[Vary]) -> Staged {
    let n = vary.len() as u32;
    let (parts, exported) = classify(l, vary);
    let mut s = Staged {
        inputs: n,
        ..Staged::default()
    };
    // Where each instruction's value is: in its part, and as an input of
    // the later parts when exported.
    let mut local = vec![Operand::Const(0.0); l.instrs.len()];
    let mut global = vec![Operand::Const(0.0); l.instrs.len()];
    for pass in [Part::Fixed, Part::Uniform, Part::Lane] {
        let first_input = n + match pass {
            Part::Fixed => 0,
            Part::Uniform => s.fixed.outputs.len() as u32,
            Part::Lane => (s.fixed.outputs.len() + s.uniform.outputs.len()) as u32,
        };
        let out = match pass {
            Part::Fixed => &mut s.fixed,
            Part::Uniform => &mut s.uniform,
            Part::Lane => &mut s.lane,
        };
        for (k, i) in l.instrs.iter().enumerate() {
            if parts[k] != pass {
                continue;
            }
            let map = |o: Operand| match o {
                Operand::Val(v) if parts[v as usize] == pass => local[v as usize],
                Operand::Val(v) => global[v as usize],
                other => other,
            };
            let (a, b) = (map(i.a), map(i.b));
            local[k] = Operand::Val(out.instrs.len() as u32);
            out.instrs.push(Instr { op: i.op, a, b });
            if exported[k] {
                global[k] = Operand::Input(first_input + out.outputs.len() as u32);
                out.outputs.push(local[k]);
            }
        }
    }
    s.lane.outputs = l
        .outputs
        .iter()
        .map(|o| match *o {
            Operand::Val(v) if parts[v as usize] == Part::Lane => local[v as usize],
            Operand::Val(v) => global[v as usize],
            other => other,
        })
        .collect();
    s
}

#[cfg(test)]
mod tests {
    use super::super::{compile, lower::lower, Dag};
    use super::*;

    #[test]
    fn time_terms_leave_the_lane_part() {
        let mut d = Dag::new();
        // q varies per lane and step, eps per lane, n per step only.
        let names = ["q", "eps", "n"];
        let roots = [compile(&mut d, "q*cos(0.1*n) + eps^2*sin(q)", &names).unwrap()];
        let l = lower(&d, &roots);
        let vary = [
            Vary {
                lane: true,
                step: true,
            },
            Vary {
                lane: true,
                step: false,
            },
            Vary {
                lane: false,
                step: true,
            },
        ];
        let s = split(&l, &vary);
        assert_eq!(s.fixed.instrs.len(), 1, "eps²: {:?}", s.fixed);
        assert_eq!(s.uniform.instrs.len(), 2, "0.1·n, its cosine");
        assert_eq!(s.lane.instrs.len(), 4, "sin q, two products, the sum");
        assert_eq!(s.fixed.outputs.len() + s.uniform.outputs.len(), 2);
        assert!(s.scalar_in_lane(4, &vary), "the cosine is one value");
        assert!(!s.scalar_in_lane(3, &vary), "eps² is per lane");
        assert!(s.scalar_in_lane(2, &vary), "n is one value");
    }
}
