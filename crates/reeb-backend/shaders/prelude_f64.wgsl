// reeb prelude, f64 (needs SHADER_F64): the working precision and the
// primitives that shared functions call (CPU twins: crates/reeb-core/src/num/prims.rs). Nothing here
// uses a WGSL builtin that lavapipe gets wrong in f64 (exp, sin, cos, ...):
// reeb's own polynomials (crates/reeb-core/src/num/math.rs) replace them.

alias R = f64;

// 2^n, exact, for n in [-1088, 1039], built from f32 powers of two without
// 64-bit integers: n = 16k + r, 2^n = (2^k)^16 · 2^r, every product exact.
fn pow2i(n: i32) -> f64 {
    let k = n >> 4u;
    let r = n - (k << 4u);
    var a = f64(bitcast<f32>(u32(k + 127) << 23u));
    a = a * a;
    a = a * a;
    a = a * a;
    a = a * a;
    return a * f64(bitcast<f32>(u32(r + 127) << 23u));
}

fn to_i32(x: f64) -> i32 {
    return i32(x);
}

// Nearest integer, ties to even. (Adding and taking away 1.5·2^52 instead
// measured 9 % slower on an H200, and drivers fold (x + c) - c to x.)
fn rint(x: f64) -> f64 {
    return round(x);
}

// 2^n for an integer-valued n in [-1023, 1024]: +0 at -1023, +inf at 1024.
// Filled in per adapter (crates/reeb-backend/src/backend/gpu/codegen.rs, `launched`):
// with SHADER_INT64 from the bits, as the CPU's twin; without, from f32
// powers of two (pow2i), with two conversions more.
{{POW2_F64}}

fn from_i32(n: i32) -> f64 {
    return f64(n);
}

fn inf() -> f64 {
    return f64(bitcast<f32>(0x7f800000u));
}

// The quiet NaN, a constant (CPU twin: Prims::quiet_nan): lavapipe folds ∞·0
// to 0, so a NaN made by arithmetic is lost there.
fn quiet_nan() -> f64 {
    return f64(bitcast<f32>(0x7fc00000u));
}

fn finite(x: f64) -> bool {
    return abs(x) <= 1.7976931348623157e308;
}

fn exp_r(x: f64) -> f64 {
    return exp_f64(x);
}

fn log_r(x: f64) -> f64 {
    return log_split_f64(x);
}

// The chaos indicators' ln x: log_r's bits, as on the CPU. Filled in per
// adapter (crates/reeb-backend/src/backend/gpu/codegen.rs): with SHADER_INT64, 2^k·m with m in
// [√½, √2) read from the bits offset by √½'s (the CPU's log_normal_f64),
// so that log_core_f64's compare, selects and halving fall away.
{{SAMPLE_LOG_F64}}

// ln x, log_f64's kernel on x = 2^e·m (m in [1, 2)): filled in per
// adapter (crates/reeb-backend/src/backend/gpu/codegen.rs, `launched`): with SHADER_INT64
// e and m from the bits, as the CPU's log_f64_bits; without, log_f64's
// ladder of scalings. Both exact, so the same bits.
{{LOG_SPLIT_F64}}

fn atan_r(x: f64) -> f64 {
    return atan_f64(x);
}

fn sincos_r(x: f64, s: ptr<function, f64>, c: ptr<function, f64>) {
    sincos_f64(x, s, c);
}

fn sin_r(x: f64) -> f64 {
    var s: f64;
    var c: f64;
    sincos_f64(x, &s, &c);
    return s;
}

fn cos_r(x: f64) -> f64 {
    var s: f64;
    var c: f64;
    sincos_f64(x, &s, &c);
    return c;
}
