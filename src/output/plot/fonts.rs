//! The fonts: DejaVu Sans, embedded, for every text; for a title with
//! characters it lacks (CJK above all) a font of the system that has them,
//! else the replacement character and one warning naming them, never
//! silent boxes.

use std::collections::BTreeSet;
use std::path::Path;
use std::sync::{Mutex, OnceLock};

use ab_glyph::{Font, FontRef};
use plotters::style::{register_font, FontStyle};

use super::figure::PlotError;

/// The family every text is drawn in.
pub(super) const FONT: &str = "sans-serif";
/// The family of the characters of a title that `FONT` lacks.
const FALLBACK: &str = "reeb-fallback";
const FONT_BYTES: &[u8] = include_bytes!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/assets/DejaVuSans.ttf"
));
/// Drawn for a character no font has.
const REPLACEMENT: char = '\u{fffd}';
/// Where the common systems keep fonts with CJK glyphs (Noto Sans CJK,
/// WenQuanYi, Droid Sans Fallback; macOS; Windows), tried in this order.
const SYSTEM_FONTS: &[&str] = &[
    "/usr/share/fonts/opentype/noto/NotoSansCJK-Regular.ttc",
    "/usr/share/fonts/noto-cjk/NotoSansCJK-Regular.ttc",
    "/usr/share/fonts/google-noto-cjk/NotoSansCJK-Regular.ttc",
    "/usr/share/fonts/opentype/noto/NotoSansCJKsc-Regular.otf",
    "/usr/share/fonts/truetype/wqy/wqy-microhei.ttc",
    "/usr/share/fonts/truetype/wqy/wqy-zenhei.ttc",
    "/usr/share/fonts/wenquanyi/wqy-microhei/wqy-microhei.ttc",
    "/usr/share/fonts/truetype/droid/DroidSansFallbackFull.ttf",
    "/usr/share/fonts/google-droid-sans-fonts/DroidSansFallbackFull.ttf",
    "/System/Library/Fonts/Hiragino Sans GB.ttc",
    "/System/Library/Fonts/Supplemental/Arial Unicode.ttf",
    "/Library/Fonts/Arial Unicode.ttf",
    "C:\\Windows\\Fonts\\msyh.ttc",
    "C:\\Windows\\Fonts\\simsun.ttc",
];

/// The embedded font, parsed once, for its coverage.
fn primary() -> &'static FontRef<'static> {
    static F: OnceLock<FontRef<'static>> = OnceLock::new();
    F.get_or_init(|| FontRef::try_from_slice(FONT_BYTES).expect("the embedded font parses"))
}

/// Registers the embedded font once per process. plotters' `ab_glyph`
/// backend knows no system fonts, so without this no text can be drawn.
pub(super) fn ensure_font() -> Result<(), PlotError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FONT, FontStyle::Normal, FONT_BYTES).is_ok());
    if ok {
        Ok(())
    } else {
        Err(PlotError::Font)
    }
}

fn has(font: &FontRef, c: char) -> bool {
    font.glyph_id(c).0 != 0
}

/// A fallback font, registered with plotters as `FALLBACK`, and where it
/// came from.
struct Fallback {
    font: FontRef<'static>,
    bytes: &'static [u8],
    path: String,
}

/// The fallback font, looked for once per process, when a title first
/// needs one; `Err` says what was tried.
fn fallback(needed: &[char]) -> &'static Result<Fallback, String> {
    static F: OnceLock<Result<Fallback, String>> = OnceLock::new();
    F.get_or_init(|| find_fallback(needed).and_then(register))
}

/// `REEB_FONT` if set (and then only it), else the first of `SYSTEM_FONTS`
/// that has every character in `needed` (or, if none has them all, the one
/// that has most). Only the font chosen stays in memory.
fn find_fallback(needed: &[char]) -> Result<Fallback, String> {
    if let Ok(path) = std::env::var("REEB_FONT") {
        return load(&path).ok_or_else(|| format!("REEB_FONT={path} is not a font file"));
    }
    let mut best: Option<(usize, &str)> = None;
    for path in SYSTEM_FONTS.iter().filter(|p| Path::new(p).is_file()) {
        let Ok(bytes) = std::fs::read(path) else {
            continue;
        };
        let Ok(font) = FontRef::try_from_slice(&bytes) else {
            continue;
        };
        let n = needed.iter().filter(|c| has(&font, **c)).count();
        if n == needed.len() {
            return load(path).ok_or_else(|| format!("{path} could not be read"));
        }
        if n > best.map_or(0, |b| b.0) {
            best = Some((n, path));
        }
    }
    let none = "no system font with them was found (Noto Sans CJK, WenQuanYi, Droid Sans \
                Fallback); REEB_FONT=FILE names a font to use";
    best.and_then(|(_, path)| load(path))
        .ok_or_else(|| none.into())
}

/// A font file read and parsed (the first face of a collection); its bytes
/// live as long as the process, as plotters requires.
fn load(path: &str) -> Option<Fallback> {
    let bytes: &'static [u8] = Box::leak(std::fs::read(path).ok()?.into_boxed_slice());
    let font = FontRef::try_from_slice(bytes).ok()?;
    Some(Fallback {
        font,
        bytes,
        path: path.to_string(),
    })
}

fn register(f: Fallback) -> Result<Fallback, String> {
    match register_font(FALLBACK, FontStyle::Normal, f.bytes) {
        Ok(()) => Ok(f),
        Err(_) => Err(format!("{} could not be registered with plotters", f.path)),
    }
}

/// `text` cut into runs of one font each, with that font's family:
/// characters the embedded font has, and (when a fallback font is found)
/// those only it has. A character neither has becomes `REPLACEMENT`, and
/// the first title to hold it prints a warning naming it.
pub(super) fn runs(text: &str) -> Vec<(&'static str, String)> {
    let lacking: Vec<char> = text.chars().filter(|c| !has(primary(), *c)).collect();
    if lacking.is_empty() {
        return vec![(FONT, text.to_string())];
    }
    let fb = fallback(&lacking);
    let font_of = |c: char| match fb {
        _ if has(primary(), c) => Some(0),
        Ok(f) if has(&f.font, c) => Some(1),
        _ => None,
    };
    let (runs, missing) = split(text, font_of);
    if !missing.is_empty() {
        let why = match fb {
            Ok(f) => format!("nor does {}", f.path),
            Err(e) => e.clone(),
        };
        warn_once(&missing, &why);
    }
    runs.into_iter()
        .map(|(k, s)| (if k == 0 { FONT } else { FALLBACK }, s))
        .collect()
}

/// Runs of consecutive characters with the same font (`font_of`: its
/// index, `None` for none: then `REPLACEMENT` in font 0), and the distinct
/// characters no font has, in order.
fn split(text: &str, font_of: impl Fn(char) -> Option<usize>) -> (Vec<(usize, String)>, Vec<char>) {
    let mut runs: Vec<(usize, String)> = vec![];
    let mut missing: Vec<char> = vec![];
    for c in text.chars() {
        let (k, shown) = match font_of(c) {
            Some(k) => (k, c),
            None => {
                if !missing.contains(&c) {
                    missing.push(c);
                }
                (0, REPLACEMENT)
            }
        };
        match runs.last_mut() {
            Some((last, s)) if *last == k => s.push(shown),
            _ => runs.push((k, shown.to_string())),
        }
    }
    (runs, missing)
}

/// Prints the warning about `missing` unless every one of them was named
/// before in this process (a run draws its title in several pictures).
fn warn_once(missing: &[char], why: &str) {
    static WARNED: Mutex<BTreeSet<char>> = Mutex::new(BTreeSet::new());
    let mut warned = WARNED.lock().unwrap_or_else(|e| e.into_inner());
    let new: Vec<char> = missing
        .iter()
        .copied()
        .filter(|c| warned.insert(*c))
        .collect();
    if !new.is_empty() {
        eprintln!("{}", warning(&new, why));
    }
}

/// "warning: the title's 范 (U+8303), … are drawn as �: DejaVu Sans has
/// no glyph for them; {why}".
fn warning(chars: &[char], why: &str) -> String {
    let named: Vec<String> = chars
        .iter()
        .map(|c| format!("{c} (U+{:04X})", u32::from(*c)))
        .collect();
    format!(
        "warning: the title's {} drawn as {REPLACEMENT}: DejaVu Sans has no glyph for {}; {why}",
        named.join(", ") + if chars.len() > 1 { " are" } else { " is" },
        if chars.len() > 1 { "them" } else { "it" },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_embedded_font_lacks_cjk_only() {
        let title = "Ван дер Поль — 范德波尔 — ε, τ ⁻³ …";
        let lacking: String = title.chars().filter(|c| !has(primary(), *c)).collect();
        assert_eq!(lacking, "范德波尔");
        assert!(has(primary(), REPLACEMENT));
    }

    #[test]
    fn runs_switch_font_and_replace_what_no_font_has() {
        let cjk = |c: char| ('\u{4e00}'..='\u{9fff}').contains(&c);
        let (runs, missing) = split("Ван 范德 ε", |c| Some(usize::from(cjk(c))));
        let want = [(0, "Ван "), (1, "范德"), (0, " ε")];
        assert_eq!(runs, want.map(|(k, s)| (k, s.to_string())));
        assert!(missing.is_empty());
        let (runs, missing) = split("Ван 范德范 ε", |c| (!cjk(c)).then_some(0));
        assert_eq!(runs, [(0, "Ван ��� ε".to_string())]);
        assert_eq!(missing, ['范', '德']);
        let w = warning(&missing, "no other font was found");
        assert!(w.contains("范 (U+8303), 德 (U+5FB7)"), "{w}");
    }
}
