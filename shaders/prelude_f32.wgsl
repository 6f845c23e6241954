// reeb prelude, f32: the working precision and the primitives that shared
// functions call (their CPU twins are `Prims` and `Math` in src/num/).

alias R = f32;

// 2^n, exact, for n in [-126, 127].
fn pow2i(n: i32) -> f32 {
    return bitcast<f32>(u32(n + 127) << 23u);
}

fn to_i32(x: f32) -> i32 {
    return i32(x);
}

// Nearest integer, ties to even.
fn rint(x: f32) -> f32 {
    return round(x);
}

// 2^n in two normal halves for n = round(y): lo = 2^floor(n/2), hi = 2^(n - floor(n/2))
// (the CPU's twin reads n from the bits of y + 1.5·2^mantissa).
fn pow2_halves(y: f32, lo: ptr<function, f32>, hi: ptr<function, f32>) {
    let n = i32(round(y));
    let n1 = n >> 1u;
    *lo = pow2i(n1);
    *hi = pow2i(n - n1);
}

fn from_i32(n: i32) -> f32 {
    return f32(n);
}

fn inf() -> f32 {
    return bitcast<f32>(0x7f800000u);
}

// Finite test on the bits, so no compiler assumption about NaN/inf removes it.
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

fn exp_r(x: f32) -> f32 {
    return exp_f32(x);
}

fn log_r(x: f32) -> f32 {
    return log_f32(x);
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
