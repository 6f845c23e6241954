//! The quick-look pictures do not mislead: properties of the drawn PNGs
//! (cell heights on a log axis, the greys of cells without a value, the
//! colours of a portrait's groups) and the title's characters a font lacks.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::runs::{tmp, REEB};
use reeb::output::pictures;
use reeb::output::plot::{self, palette};
use reeb::plan::observations::Observations;
use reeb::scene::Scene;

/// A decoded RGB picture.
struct Picture {
    w: usize,
    h: usize,
    px: Vec<[u8; 3]>,
}

impl Picture {
    fn read(path: &Path) -> Self {
        let file = std::fs::File::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let mut reader = png::Decoder::new(file).read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        let step = match info.color_type {
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            other => panic!("{}: colour type {other:?}", path.display()),
        };
        let px = buf[..info.buffer_size()]
            .chunks(step)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let (w, h) = (info.width as usize, info.height as usize);
        Self { w, h, px }
    }

    fn at(&self, x: usize, y: usize) -> [u8; 3] {
        self.px[y * self.w + x]
    }
}

fn is_grey(c: [u8; 3]) -> bool {
    c[0] == c[1] && c[1] == c[2]
}

fn scene(dir: &Path, text: &str) -> Scene {
    let path = dir.join("scene.toml");
    std::fs::write(&path, text).unwrap();
    Scene::load(&path).unwrap()
}

/// Observations of `n` trajectories with nothing recorded yet.
fn observations(n: usize) -> Observations<f64> {
    Observations::bare(n)
}

/// The runs of one colour (not a grey, so neither text nor background)
/// down column `x`, longer than 3 pixels: (colour, length).
fn coloured_runs(p: &Picture, x: usize) -> Vec<([u8; 3], usize)> {
    let mut runs: Vec<([u8; 3], usize)> = vec![];
    for y in 0..p.h {
        let c = p.at(x, y);
        match runs.last_mut() {
            Some((last, n)) if *last == c => *n += 1,
            _ => runs.push((c, 1)),
        }
    }
    runs.retain(|(c, n)| !is_grey(*c) && *n > 3);
    runs
}

/// van_der_pol_stiff's dt (10⁻² to 10⁻⁴, not geometric) on a heat map: on
/// a linear axis its three smallest values were slivers of 3 % of the map
/// (and a tick read 0.000); on a log axis each row gets at least 10 %.
#[test]
fn a_dt_axis_over_two_decades_is_drawn_logarithmic() {
    let dir = tmp("pictures", "log_axis");
    let s = scene(
        &dir,
        r#"model = "van_der_pol"
[params]
epsilon = [25.0, 50.0, 100.0]
[initial]
q = 2.0
s = 0.0
[integrator]
scheme = "s2"
dt = [1e-2, 5e-3, 1e-3, 5e-4, 1e-4]
steps = 10
[output]
final = ["q"]
"#,
    );
    assert_eq!(s.shape(), vec![3, 5]);
    // One colour per dt: its index.
    let mut d = observations(15);
    let row: Vec<f64> = (0..15).map(|i| (i % 5) as f64 + 1.0).collect();
    d.final_values.push(("q".into(), row));
    pictures::draw(&s, &dir, &d, &Default::default()).unwrap();
    let p = Picture::read(&dir.join("final_q.png"));
    let runs = coloured_runs(&p, p.w * 2 / 5);
    assert_eq!(runs.len(), 5, "{runs:?}");
    let total: usize = runs.iter().map(|r| r.1).sum();
    for (c, n) in &runs {
        assert!(
            *n * 10 >= total,
            "a row of {n} of {total} pixels ({c:?}): {runs:?}"
        );
    }
}

/// A 3 × 3 van der Pol map: cells 0, 1 and 3 found no cycle (their
/// amplitude array holds a half-range all the same), cell 2 stopped: all
/// in the left two columns of the map.
fn cycle_observations() -> Observations<f64> {
    let mut d = observations(9);
    d.final_values.push(("q".into(), vec![1.0; 9]));
    d.cycle_amplitude = (0..9).map(|i| 2.0 + 0.01 * i as f64).collect();
    d.cycle_period = (0..9).map(|i| 6.0 + 0.1 * i as f64).collect();
    for i in [0, 1, 3] {
        d.cycle_amplitude[i] = 0.4;
        d.cycle_period[i] = f64::NAN;
    }
    d.cycle_amplitude[2] = f64::NAN;
    d.cycle_period[2] = f64::NAN;
    d.final_values[0].1[2] = f64::NAN;
    d.nonfinite_step[2] = 17;
    d
}

/// The grey levels covering at least `min` pixels left of `x_max`.
fn grey_areas(p: &Picture, x_max: usize, min: usize) -> Vec<u8> {
    let mut count = [0usize; 256];
    for y in 0..p.h {
        for x in 0..x_max {
            let c = p.at(x, y);
            if is_grey(c) && (30..240).contains(&c[0]) {
                count[c[0] as usize] += 1;
            }
        }
    }
    (0..256)
        .filter(|g| count[*g] >= min)
        .map(|g| g as u8)
        .collect()
}

/// Cells without a cycle showed the amplitude array's half-range as if it
/// were a cycle's; now they are grey, another grey than the stopped
/// trajectory's, and both greys have a swatch beside the colour bar.
#[test]
fn cells_without_a_cycle_are_grey_with_a_legend_entry() {
    let dir = tmp("pictures", "no_cycle");
    let s = scene(
        &dir,
        r#"model = "van_der_pol"
[params]
epsilon = { linspace = [1.0, 3.0, 3] }
[initial]
q = { linspace = [1.0, 3.0, 3] }
s = 0.0
[integrator]
scheme = "s2"
dt = 0.01
steps = 10
[output]
final = ["q"]
cycle = true
"#,
    );
    let d = cycle_observations();
    pictures::draw(&s, &dir, &d, &Default::default()).unwrap();
    for file in ["cycle_amplitude.png", "cycle_period.png"] {
        let p = Picture::read(&dir.join(file));
        // The map: three cells of about 6 % of the image each, and one.
        let map = grey_areas(&p, p.w * 6 / 10, p.w * p.h / 40);
        assert_eq!(map.len(), 2, "{file}: grey areas {map:?}");
        // Right of the map's grey cells: only the swatches are grey.
        let beside = |g: &u8| {
            let n = (0..p.h)
                .flat_map(|y| (p.w * 6 / 10..p.w).map(move |x| (x, y)))
                .filter(|&(x, y)| p.at(x, y) == [*g; 3])
                .count();
            n >= 200
        };
        assert!(map.iter().all(beside), "{file}: no swatch of {map:?}");
    }
    // The stopped trajectory's final value is grey too.
    let p = Picture::read(&dir.join("final_q.png"));
    assert_eq!(grey_areas(&p, p.w * 6 / 10, p.w * p.h / 40).len(), 1);
}

/// Pixel `c` is palette colour `k` laid over white at opacity 0.55 to 1.
fn shade_of(c: [u8; 3], k: [u8; 3]) -> bool {
    (55..=100).any(|a| {
        let a = f64::from(a) / 100.0;
        (0..3).all(|j| {
            let want = 255.0 + a * (f64::from(k[j]) - 255.0);
            (f64::from(c[j]) - want).abs() <= 3.0
        })
    })
}

/// A Poincaré portrait of 100 orbits in ten colour bands, every band
/// spread over the same ring (orbits on one attractor, as Duffing's): a
/// mean of the colours turned every pixel one grey-brown that no legend
/// entry shows; each band's colour must be what one sees in some pixels.
#[test]
fn a_portrait_shows_every_group_colour() {
    let dir = tmp("pictures", "portrait");
    let s = scene(
        &dir,
        r#"model = "van_der_pol"
[params]
epsilon = 1.0
[initial]
q = { linspace = [0.5, 2.5, 100] }
s = 0.0
[integrator]
scheme = "s2"
dt = 0.01
steps = 10
[output]
final = ["q"]
poincare = { period = 1.0, max_points = 5000, vars = ["q", "s"] }
"#,
    );
    let (n, m) = (100, 5000);
    let mut d = observations(n);
    d.max_points = m;
    d.poincare_count = vec![m as u32; n];
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let (mut q, mut p) = (vec![0.0; n * m], vec![0.0; n * m]);
    for k in 0..n * m {
        let (a, r) = (std::f64::consts::TAU * uniform(), 1.0 + 0.05 * uniform());
        (q[k], p[k]) = (r * a.cos(), r * a.sin());
    }
    d.poincare = vec![("q".into(), q), ("s".into(), p)];
    pictures::draw(&s, &dir, &d, &Default::default()).unwrap();
    let pic = Picture::read(&dir.join("poincare.png"));
    let colours: Vec<[u8; 3]> = (0..10).map(|k| palette(k).into()).collect();
    let seen: Vec<usize> = colours
        .iter()
        .map(|k| pic.px.iter().filter(|c| shade_of(**c, *k)).count())
        .collect();
    let shown = seen.iter().filter(|c| **c >= 1000).count();
    assert!(shown >= 9, "pixels of each band's colour: {seen:?}");
}

/// Runs `scene` with `REEB_FONT` set to the embedded font (DejaVu Sans,
/// without CJK), so no system font can step in; returns stderr.
fn run_with_dejavu(scene: &Path, out: &Path) -> String {
    let font = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/DejaVuSans.ttf");
    let o = Command::new(REEB)
        .args([
            "run",
            scene.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .env("REEB_FONT", &font)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    err
}

fn titled(dir: &Path, name: &str, title: &str) -> PathBuf {
    let path = dir.join(format!("{name}.toml"));
    let text = format!(
        r#"title = "{title}"
model = "van_der_pol"
[params]
epsilon = [1.0, 2.0, 3.0]
[initial]
q = 2.0
s = 0.0
[integrator]
scheme = "s2"
dt = 0.01
steps = 10
[output]
final = ["q", "s"]
"#
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// A title with characters no font at hand has: they are drawn as "�"
/// (not as the font's empty boxes), and one warning names them, however
/// many pictures carry the title.
#[test]
fn title_characters_the_font_lacks_are_named_once_and_drawn_as_replacements() {
    let dir = tmp("pictures", "title");
    let cjk = titled(&dir, "cjk", "Ван дер Поль — 范德波尔 — ε, τ");
    let marked = titled(&dir, "marked", "Ван дер Поль — ���� — ε, τ");
    let err = run_with_dejavu(&cjk, &dir.join("cjk"));
    let named = "范 (U+8303), 德 (U+5FB7), 波 (U+6CE2), 尔 (U+5C14)";
    assert_eq!(err.matches(named).count(), 1, "{err}");
    assert!(!run_with_dejavu(&marked, &dir.join("marked")).contains("warning"));
    for file in ["final_q.png", "final_s.png"] {
        let a = Picture::read(&dir.join("cjk").join(file));
        let b = Picture::read(&dir.join("marked").join(file));
        assert!(a.px == b.px, "{file}: the title's CJK is not drawn as �");
    }
}

/// Pixels of colour `c` in the title band (top 40 rows) or the right
/// margin (last 20 columns): nothing of a plot's data belongs there.
fn outside_the_chart(p: &Picture, c: [u8; 3]) -> usize {
    (0..p.h)
        .flat_map(|y| (0..p.w).map(move |x| (x, y)))
        .filter(|&(x, y)| (y < 40 || x + 20 >= p.w) && p.at(x, y) == c)
        .count()
}

/// Thick polylines whose points repeat or turn back on themselves (a
/// trajectory sampled finely, a stiff one's hairpins): plotters' joins
/// turned those into straight spikes across the picture, into the title
/// and beyond the frame (forced_van_der_pol_work_precision's portrait).
#[test]
fn thick_lines_stay_inside_the_chart() {
    let dir = tmp("pictures", "spikes");
    let n = 20_000;
    let t: Vec<f64> = (0..n)
        .map(|i| i as f64 * std::f64::consts::TAU / n as f64)
        .collect();
    // A Lissajous figure sampled far finer than a pixel, and a zig-zag of
    // hairpins (a step that overshoots and comes back, over and over).
    let (x1, y1): (Vec<f64>, Vec<f64>) = t.iter().map(|t| (t.cos(), (3.0 * t).sin())).unzip();
    let x2: Vec<f64> = (0..400)
        .map(|i| if i % 2 == 0 { 0.8 } else { 1.0 })
        .collect();
    let y2: Vec<f64> = (0..400).map(|i| -0.3 + 0.0015 * i as f64).collect();
    let series = [
        plot::Series::new("a", &x1, &y1),
        plot::Series::new("b", &x2, &y2),
    ];
    let fig = plot::Figure {
        title: "spikes",
        ..plot::Figure::default()
    };
    let path = dir.join("lines.png");
    plot::lines(&path, &fig, &series, false, false).unwrap();
    let p = Picture::read(&path);
    for k in 0..2 {
        let c: [u8; 3] = palette(k).into();
        assert_eq!(outside_the_chart(&p, c), 0, "series {k}");
    }
}
