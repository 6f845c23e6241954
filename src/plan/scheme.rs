//! Schemes as data (SPEC §1.2, §3): the second-order splitting S2 with an inner
//! piece order, its symmetric compositions given by weight lists, and the
//! comparison integrators.

use crate::models::spec::Method;

/// Triple-jump pair `(γ1, γ0)` raising an order-2k method to order 2k+2:
/// `γ1 = 1/(2 − 2^{1/(2k+1)})`, `γ0 = −2^{1/(2k+1)}/(2 − 2^{1/(2k+1)})`.
pub fn triple_jump_pair(target_order: u32) -> (f64, f64) {
    let k = (target_order - 2) / 2;
    let r = 2f64.powf(1.0 / (2 * k + 1) as f64);
    (1.0 / (2.0 - r), -r / (2.0 - r))
}

/// Yoshida (1990) sixth-order weights `w1, w2, w3` (SPEC §1.2).
pub const YOSHIDA6: [(char, [f64; 3]); 3] = [
    (
        'a',
        [-1.17767998417887, 0.235573213359357, 0.784513610477560],
    ),
    (
        'b',
        [-2.13228522200144, 0.00426068187079180, 1.43984816797678],
    ),
    (
        'c',
        [0.00152886228424922, -2.14403531630539, 1.44778256239930],
    ),
];

/// Yoshida (1990) eighth-order weights `w1 … w7` (SPEC §1.2).
pub const YOSHIDA8: [(char, [f64; 7]); 5] = [
    (
        'a',
        [
            -1.61582374150097,
            -2.44699182370524,
            -0.00716989419708120,
            2.44002732616735,
            0.157739928123617,
            1.82020630970714,
            1.04242620869991,
        ],
    ),
    (
        'b',
        [
            -0.00169248587770116,
            2.89195744315849,
            0.00378039588360192,
            -2.89688250328827,
            2.89105148970595,
            -2.33864815101035,
            1.48819229202922,
        ],
    ),
    (
        'c',
        [
            0.311790812418427,
            -1.55946803821447,
            -1.67896928259640,
            1.66335809963315,
            -1.06458714789183,
            1.36934946416871,
            0.629030650210433,
        ],
    ),
    (
        'd',
        [
            0.102799849391985,
            -1.96061023297549,
            1.93813913762276,
            -0.158240635368243,
            -1.44485223686048,
            0.253693336566229,
            0.914844246229740,
        ],
    ),
    (
        'e',
        [
            0.0227738840094906,
            2.52778927322839,
            -0.0719180053552772,
            0.00536018921307285,
            -2.04809795887393,
            0.107990467703699,
            1.30300165760014,
        ],
    ),
];

/// The symmetric list `w_m … w_1 w_0 w_1 … w_m` from `w_1 … w_m`, with
/// `w_0 = 1 − 2 Σ w_j` recomputed in f64 (SPEC §1.2: never typed).
fn symmetric(w: &[f64]) -> Vec<f64> {
    let w0 = 1.0 - 2.0 * w.iter().sum::<f64>();
    let mut out: Vec<f64> = w.iter().rev().copied().collect();
    out.push(w0);
    out.extend(w.iter().copied());
    out
}

/// Weights of the triple jump iterated up to `order` (2 → [1]; 4 → 3 stages;
/// 6 → 9; 8 → 27), outermost level the highest-order pair.
pub fn triple_jump_weights(order: u32) -> Vec<f64> {
    let mut w = vec![1.0];
    let mut o = 4;
    while o <= order {
        let (g1, g0) = triple_jump_pair(o);
        w = [g1, g0, g1]
            .iter()
            .flat_map(|g| w.iter().map(move |x| g * x))
            .collect();
        o += 2;
    }
    w
}

/// How a scheme advances one step.
#[derive(Debug, Clone, PartialEq)]
pub enum SchemeKind {
    /// `S(τ) = S2(w_m τ) … S2(w_0 τ) … S2(w_m τ)` with the listed weights.
    Splitting { weights: Vec<f64> },
    /// A comparison integrator.
    Method(Method),
}

/// A named integration scheme.
#[derive(Debug, Clone, PartialEq)]
pub struct Scheme {
    pub name: String,
    pub kind: SchemeKind,
    /// Nominal order of accuracy.
    pub order: u32,
}

impl std::fmt::Display for Scheme {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.name)
    }
}

/// A scheme is written (summary.json, report settings) by its name.
impl serde::Serialize for Scheme {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&self.name)
    }
}

/// Every scheme name a scene may use.
pub const SCHEME_NAMES: &[&str] = &[
    "s2",
    "triple_jump4",
    "triple_jump6",
    "triple_jump8",
    "yoshida6a",
    "yoshida6b",
    "yoshida6c",
    "yoshida8a",
    "yoshida8b",
    "yoshida8c",
    "yoshida8d",
    "yoshida8e",
    "variational1",
    "variational2",
    "rk4",
    "leapfrog",
];

impl Scheme {
    /// The scheme called `name` (one of [`SCHEME_NAMES`]).
    pub fn by_name(name: &str) -> Option<Scheme> {
        let split = |weights: Vec<f64>, order| Scheme {
            name: name.to_string(),
            kind: SchemeKind::Splitting { weights },
            order,
        };
        let method = |m: Method| Scheme {
            name: name.to_string(),
            kind: SchemeKind::Method(m),
            order: m.order(),
        };
        Some(match name {
            "s2" => split(vec![1.0], 2),
            "triple_jump4" => split(triple_jump_weights(4), 4),
            "triple_jump6" => split(triple_jump_weights(6), 6),
            "triple_jump8" => split(triple_jump_weights(8), 8),
            "variational1" => method(Method::Variational1),
            "variational2" => method(Method::Variational2),
            "rk4" => method(Method::Rk4),
            "leapfrog" => method(Method::Leapfrog),
            _ => {
                let family = name.chars().last()?;
                if let Some(rest) = name.strip_prefix("yoshida6") {
                    let (_, w) = YOSHIDA6
                        .iter()
                        .find(|(c, _)| rest.len() == 1 && *c == family)?;
                    split(symmetric(w), 6)
                } else if let Some(rest) = name.strip_prefix("yoshida8") {
                    let (_, w) = YOSHIDA8
                        .iter()
                        .find(|(c, _)| rest.len() == 1 && *c == family)?;
                    split(symmetric(w), 8)
                } else {
                    return None;
                }
            }
        })
    }

    /// Flow (or right-hand-side) evaluations per step (SPEC §6): S2 stages for
    /// splittings, force evaluations for the comparison methods.
    pub fn evaluations(&self) -> u32 {
        match &self.kind {
            SchemeKind::Splitting { weights } => weights.len() as u32,
            SchemeKind::Method(m) => m.evaluations(),
        }
    }

    pub fn is_splitting(&self) -> bool {
        matches!(self.kind, SchemeKind::Splitting { .. })
    }
}

/// The inner order of S2, e.g. `CBABC`: a palindrome of odd length naming each
/// piece of the model exactly once per side. Returns the outer-to-middle
/// sequence `P1 … Pm`.
pub fn parse_order(order: &str, pieces: &str) -> Result<Vec<char>, String> {
    let chars: Vec<char> = order.chars().collect();
    let m = pieces.chars().count();
    if chars.len() != 2 * m - 1 {
        return Err(format!(
            "`{order}` has {} letters; an S2 order of this model's {m} pieces ({pieces}) has {}, e.g. `CBABC`",
            chars.len(),
            2 * m - 1
        ));
    }
    if chars.iter().ne(chars.iter().rev()) {
        return Err(format!("`{order}` is not a palindrome (S2 is symmetric)"));
    }
    let half: Vec<char> = chars[..m].to_vec();
    for p in pieces.chars() {
        if half.iter().filter(|&&c| c == p).count() != 1 {
            return Err(format!(
                "`{order}` must name each piece of {pieces} exactly once up to its middle"
            ));
        }
    }
    Ok(half)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::excessive_precision)] // SPEC's table, digit for digit
    fn triple_jump_pairs_match_the_table() {
        let table = [
            (4, 1.351207191959657634047688, -1.702414383919315268095376),
            (6, 1.174671758089363384495069, -1.349343516178726768990139),
            (8, 1.116182939325385791126848, -1.232365878650771582253695),
        ];
        for (o, g1, g0) in table {
            let (a, b) = triple_jump_pair(o);
            assert!(
                (a - g1).abs() < 1e-15 && (b - g0).abs() < 1e-15,
                "order {o}"
            );
        }
    }

    #[test]
    fn weights_are_consistent() {
        for name in SCHEME_NAMES {
            let s = Scheme::by_name(name).unwrap();
            if let SchemeKind::Splitting { weights } = &s.kind {
                let sum: f64 = weights.iter().sum();
                assert!((sum - 1.0).abs() < 1e-13, "{name}: {sum}");
                assert!(
                    weights.iter().eq(weights.iter().rev()),
                    "{name} not symmetric"
                );
            }
        }
        assert_eq!(Scheme::by_name("triple_jump6").unwrap().evaluations(), 9);
        assert_eq!(Scheme::by_name("triple_jump8").unwrap().evaluations(), 27);
        assert_eq!(Scheme::by_name("yoshida8c").unwrap().evaluations(), 15);
        // SPEC's w0 column, recomputed.
        let w = |n: &str| match Scheme::by_name(n).unwrap().kind {
            SchemeKind::Splitting { weights } => weights[weights.len() / 2],
            _ => unreachable!(),
        };
        assert!((w("yoshida6a") - 1.315186320683906).abs() < 1e-12);
        assert!((w("yoshida8e") + 2.6937990150511705).abs() < 1e-12);
        assert!(Scheme::by_name("yoshida6d").is_none());
        assert!(Scheme::by_name("yoshida6").is_none());
    }

    #[test]
    fn orders_parse() {
        assert_eq!(parse_order("CBABC", "ABC").unwrap(), vec!['C', 'B', 'A']);
        assert!(parse_order("CBACB", "ABC").is_err());
        assert!(parse_order("CCACC", "ABC").is_err());
        assert!(parse_order("CBA", "ABC").is_err());
    }
}
