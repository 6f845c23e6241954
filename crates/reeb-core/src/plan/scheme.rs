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

/// A published symmetric composition of S2 (SPEC §1.3), listed from the
/// outermost weight inward, the middle weight left out: it is recomputed as
/// `1 − 2 Σ` like Yoshida's `w_0`, and a test compares it with `middle`, the
/// published value.
pub struct Composition {
    pub name: &'static str,
    pub order: u32,
    pub outer: &'static [f64],
    pub middle: f64,
    /// Where the digits come from.
    pub source: &'static str,
}

/// The better compositions of SPEC §1.3: far smaller error constants than
/// Yoshida's or the triple jump at the same number of stages. The digits are
/// the drift coefficients `a_i` of OrdinaryDiffEq.jl's symplectic tableaus
/// (`KahanLi6`, `KahanLi8`, `SofSpa10`), which are these weights; McLachlan's
/// order-4 scheme is the one of Hairer, Lubich & Wanner, *Geometric Numerical
/// Integration* (2006), §V.3.2, where γ1 = 0.28 is his choice and γ2 solves
/// Σγ³ = 0. `tests::compositions_satisfy_their_order_conditions` checks each
/// against the order conditions, not only the digits.
#[allow(clippy::excessive_precision)] // the published digits, as published
pub const COMPOSITIONS: &[Composition] = &[
    Composition {
        name: "mclachlan4",
        order: 4,
        outer: &[0.28, 0.62546642846767004501],
        middle: -0.81093285693534009002,
        source: "McLachlan (1995), SIAM J. Sci. Comput. 16, 151–168: s = 5, order 4",
    },
    Composition {
        name: "kahanli6",
        order: 6,
        outer: &[
            0.39216144400731413927925056,
            0.33259913678935943859974864,
            -0.70624617255763935980996482,
            0.08221359629355080023149045,
        ],
        middle: 0.79854399093482996339895035,
        source: "Kahan & Li (1997), Math. Comp. 66, 1089–1099: s9odr6a",
    },
    Composition {
        name: "kahanli8",
        order: 8,
        outer: &[
            0.13020248308889008087881763,
            0.56116298177510838456196441,
            -0.38947496264484728640807860,
            0.15884190655515560089621075,
            -0.39590389413323757733623154,
            0.18453964097831570709183254,
            0.25837438768632204729397911,
            0.29501172360931029887096624,
        ],
        middle: -0.60550853383003451169892108,
        source: "Kahan & Li (1997), Math. Comp. 66, 1089–1099: s17odr8a",
    },
    Composition {
        name: "sofspa10",
        order: 10,
        outer: &[
            0.07879572252168641926390768,
            0.31309610341510852776481247,
            0.02791838323507806610952027,
            -0.22959284159390709415121340,
            0.13096206107716486317465686,
            -0.26973340565451071434460973,
            0.07497334315589143566613711,
            0.11199342399981020488957508,
            0.36613344954622675119314812,
            -0.39910563013603589787862981,
            0.10308739852747107731580277,
            0.41143087395589023782070412,
            -0.00486636058313526176219566,
            -0.39203335370863990644808194,
            0.05194250296244964703718290,
            0.05066509075992449633587434,
            0.04967437063972987905456880,
        ],
        middle: 0.04931773575959453791768001,
        source: "Sofroniou & Spaletta (2005), Optim. Methods Softw. 20, 597–613: s35odr10",
    },
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
    "mclachlan4",
    "kahanli6",
    "kahanli8",
    "sofspa10",
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
                if let Some(c) = COMPOSITIONS.iter().find(|c| c.name == name) {
                    let inner: Vec<f64> = c.outer.iter().rev().copied().collect();
                    return Some(split(symmetric(&inner), c.order));
                }
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

    /// Truncated series in the free associative algebra on the letters
    /// `B_1, B_3, B_5, …` (a word is its letters' weights).
    type Series = std::collections::BTreeMap<Vec<u8>, f64>;

    fn weight(word: &[u8]) -> u32 {
        word.iter().map(|&k| k as u32).sum()
    }

    fn product(a: &Series, b: &Series, max: u32) -> Series {
        let mut out = Series::new();
        for (u, x) in a {
            for (v, y) in b {
                if weight(u) + weight(v) <= max {
                    let w: Vec<u8> = u.iter().chain(v).copied().collect();
                    *out.entry(w).or_default() += x * y;
                }
            }
        }
        out
    }

    /// `exp(x)` for `x` without a constant term, to weight `max`.
    fn exp(x: &Series, max: u32) -> Series {
        let mut term = Series::from([(vec![], 1.0)]);
        let mut sum = term.clone();
        for k in 1..=max {
            term = product(&term, x, max);
            term.values_mut().for_each(|c| *c /= k as f64);
            for (w, c) in &term {
                *sum.entry(w.clone()).or_default() += c;
            }
        }
        sum
    }

    /// The composition's defect against the exact flow, per word: with the
    /// basic method `S2(h) = exp(h B_1 + h³ B_3 + h⁵ B_5 + …)` (symmetric, so
    /// only odd powers), `Π_i S2(w_i h) − exp(h B_1)`, to weight `max`. The
    /// order conditions of a composition of order p are exactly that every
    /// word of weight ≤ p vanishes (the letters are generic, so this is
    /// McLachlan's (1995) set of conditions, not a sufficient subset).
    fn defect(weights: &[f64], max: u32) -> Series {
        let stage = |w: f64| -> Series {
            (1..=max)
                .step_by(2)
                .map(|k| (vec![k as u8], w.powi(k as i32)))
                .collect()
        };
        let mut psi = Series::from([(vec![], 1.0)]);
        for &w in weights {
            psi = product(&psi, &exp(&stage(w), max), max);
        }
        for (word, c) in exp(&Series::from([(vec![1], 1.0)]), max) {
            *psi.entry(word).or_default() -= c;
        }
        psi
    }

    #[test]
    fn compositions_satisfy_their_order_conditions() {
        let names = ["triple_jump4", "yoshida6a", "yoshida8d", "triple_jump8"];
        let compositions = COMPOSITIONS.iter().map(|c| c.name);
        for name in names.into_iter().chain(compositions) {
            let s = Scheme::by_name(name).unwrap();
            let SchemeKind::Splitting { weights } = &s.kind else {
                unreachable!()
            };
            let p = s.order;
            let d = defect(weights, p + 1);
            let worst = |keep: &dyn Fn(u32) -> bool| {
                d.iter()
                    .filter(|(w, _)| keep(weight(w)))
                    .map(|(_, c)| c.abs())
                    .fold(0.0, f64::max)
            };
            // Yoshida's digits are published to 15 places; the others to
            // 20 or more, so round-off of the sums in f64 is what is left.
            let tol = if name.starts_with("yoshida") {
                1e-11
            } else {
                1e-12
            };
            let below = worst(&|w| w <= p);
            eprintln!("{name}: order {p} conditions hold to {below:.1e}");
            assert!(
                below < tol,
                "{name}: a condition of order ≤ {p} fails by {below:e}"
            );
            // …and the order is not higher: some word of weight p + 1 stays.
            let at = worst(&|w| w == p + 1);
            assert!(at > 1e-8, "{name}: order above {p}? defect {at:e}");
        }
    }

    #[test]
    fn published_middle_weights_agree_with_the_recomputed_ones() {
        for c in COMPOSITIONS {
            let s = Scheme::by_name(c.name).unwrap();
            let SchemeKind::Splitting { weights } = &s.kind else {
                unreachable!()
            };
            assert_eq!(weights.len(), 2 * c.outer.len() + 1, "{}", c.name);
            assert!(
                (weights[c.outer.len()] - c.middle).abs() < 1e-15,
                "{}",
                c.name
            );
            assert_eq!(weights[0], c.outer[0], "{}: outermost first", c.name);
            assert_eq!(s.order, c.order);
        }
    }

    #[test]
    fn orders_parse() {
        assert_eq!(parse_order("CBABC", "ABC").unwrap(), vec!['C', 'B', 'A']);
        assert!(parse_order("CBACB", "ABC").is_err());
        assert!(parse_order("CCACC", "ABC").is_err());
        assert!(parse_order("CBA", "ABC").is_err());
    }
}
