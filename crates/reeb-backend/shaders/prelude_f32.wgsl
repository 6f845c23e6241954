// reeb prelude, f32: the working precision and the primitives that shared
// functions call (their CPU twins are `Prims` and `Math` in crates/reeb-core/src/num/).

alias R = f32;

fn to_i32(x: f32) -> i32 {
    return i32(x);
}

// Nearest integer, ties to even.
fn rint(x: f32) -> f32 {
    return round(x);
}

// 2^n for an integer-valued n in [-127, 128]: +0 at -127, +inf at 128. As
// the CPU's twin: n + 127 lands in the low bits of n + 1.5·2^23 + 127, and
// the shift moves it into the exponent field. An add and a shift, where a
// float-to-integer conversion runs at a quarter of the FMA rate on NVIDIA.
fn pow2(n: f32) -> f32 {
    return bitcast<f32>(bitcast<u32>(n + 12583039.0) << 23u);
}

fn from_i32(n: i32) -> f32 {
    return f32(n);
}

fn inf() -> f32 {
    return bitcast<f32>(0x7f800000u);
}

// The quiet NaN, a constant (CPU twin: Prims::quiet_nan): lavapipe folds ∞·0
// to 0, so a NaN made by arithmetic is lost there.
fn quiet_nan() -> f32 {
    return bitcast<f32>(0x7fc00000u);
}

// Finite test on the bits, so no compiler assumption about NaN/inf removes it.
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// exp: reeb's polynomial (the CPU's function) or the adapter's exp2 on a split
// argument, as the device opened (crates/reeb-backend/src/backend/gpu/codegen.rs, ExpForm).
{{EXP_F32}}

// ln x with x = 2^e·m read from the bits rather than found by log_f32's
// ladder of scalings: the same m and e, hence the same result (the CPU's
// twin is log_f32_bits, tested bit for bit against the ladder over the
// f32), in a third of the operations.
fn log_r(x: f32) -> f32 {
    let tiny = x < 1.17549435e-38;
    let bits = bitcast<u32>(select(x, x * 4294967296.0, tiny));
    let e = f32(i32((bits >> 23u) & 0xffu) - 127 - select(0, 32, tiny));
    let m = bitcast<f32>((bits & 0x007fffffu) | 0x3f800000u);
    let normal = x > 0.0 && x <= 3.40282347e38;
    return log_kernel_f32(x, select(x, m, normal), select(0.0, e, normal));
}

// The chaos indicators' ln x: x = 2^k·(1 + f), 1 + f in [√½, √2), from
// the bits offset by √½'s, then the division-free sample_log_core_f32; the
// CPU's sample_log_f32 by the same operations.
fn sample_log_r(x: f32) -> f32 {
    let tiny = x < 1.17549435e-38;
    let ix = bitcast<u32>(select(x, x * 4294967296.0, tiny)) - 0x3f3504f3u;
    let k = f32(bitcast<i32>(ix) >> 23u) - select(0.0, 32.0, tiny);
    let f = bitcast<f32>((ix & 0x007fffffu) + 0x3f3504f3u) - 1.0;
    return sample_log_cases_f32(x, sample_log_core_f32(f, k));
}

fn atan_r(x: f32) -> f32 {
    return atan_f32(x);
}

fn sincos_r(x: f32, s: ptr<function, f32>, c: ptr<function, f32>) {
    sincos_f32(x, s, c);
}

fn sin_r(x: f32) -> f32 {
    var s: f32;
    var c: f32;
    sincos_f32(x, &s, &c);
    return s;
}

fn cos_r(x: f32) -> f32 {
    var s: f32;
    var c: f32;
    sincos_f32(x, &s, &c);
    return c;
}
