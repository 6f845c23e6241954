//! What a run produces, per trajectory, in the run's precision.

use crate::num::precision::{Precision, Real};
use crate::plan::{ObsVar, Plan};

/// Status of a trajectory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    Ok,
    /// A state variable became non-finite (overflow, a singular map such as
    /// Kepler at q = 0) at this step (1-based); the trajectory stopped there.
    NonFinite {
        step: u64,
    },
    /// The stop condition held after this step (1-based); the trajectory
    /// stopped there, its state final.
    Stopped {
        step: u64,
    },
}

/// The columns of [`Observations`], each declared once: its field, whether
/// it holds one array per observed variable (`Named`, from the plan's list)
/// or one array (`Plain`), its element type, how many values each trajectory
/// has in it (`per`: `one`, `frames`, `max_points`, …), when the plan has
/// it (`when`, every flag listed: a plain column the plan lacks is empty),
/// and its file and dimensions after the axes (`file`: a named column has
/// one per variable; a column without one is not written as it is). From
/// this list come the struct, its allocation, [`Observations::place_rows`],
/// [`Observations::convert`], [`Observations::columns`] (what snapshots
/// write and read, in this order), [`Observations::files`] (what the run
/// directory's arrays are written from and read back into), the CPU's
/// [`Sink`] and [`bytes_per_trajectory`]. A new output is one line here.
macro_rules! observations {
    ($( $(#[$doc:meta])* $field:ident: $kind:ident $(($list:ident))? $elem:ident,
        per $width:ident, when $($when:ident)&+ $(, file $file:literal [$($dim:ident),*])?; )*) => {
        /// Observations of a whole ensemble. Arrays are indexed by trajectory
        /// (the row-major index over the plan's axes), then frame or point.
        #[derive(Debug, Clone)]
        pub struct Observations<R> {
            pub n: usize,
            /// Frames per trajectory (`steps / every + 1`, from step 0).
            pub frames: usize,
            /// Poincaré points kept per trajectory.
            pub max_points: usize,
            /// Lyapunov exponents per trajectory.
            pub exponents: usize,
            /// The attractor detector's samples kept per trajectory.
            pub cycle_points: usize,
            $( $(#[$doc])* pub $field: $kind<$elem>, )*
        }

        /// Every column of an [`Observations`] as views that blocks fill in
        /// disjoint rows.
        pub struct Sink<R> {
            $( pub $field: observations!(@rows $kind $elem), )*
        }

        impl<R: Real> Observations<R> {
            /// Every array sized for `s`, NaN (counts 0).
            fn allocate(plan: &Plan, s: &Shape) -> Self {
                Observations {
                    n: s.n,
                    frames: s.per.frames as usize,
                    max_points: s.per.max_points as usize,
                    exponents: s.per.exponents as usize,
                    cycle_points: s.per.cycle_points as usize,
                    $( $field: observations!(@alloc $kind [$($list)?] $elem,
                        plan, s.n * s.per.$width as usize, $(s.$when)&&+), )*
                }
            }

            /// `n` trajectories with none of the columns a plan may lack, and
            /// no frames or points: observations to fill by hand.
            pub fn bare(n: usize) -> Self {
                Observations {
                    n,
                    frames: 0,
                    max_points: 0,
                    exponents: 0,
                    cycle_points: 0,
                    $( $field: observations!(@bare $kind $elem, n, $($when)&+), )*
                }
            }

            /// Every column in declaration order, with its values per
            /// trajectory (a named column: one per variable).
            pub fn columns(&self) -> Vec<(usize, Col<'_, R>)> {
                let s = self.widths();
                let mut out = vec![];
                $( observations!(@col $kind $elem, out, &self.$field, s.$width as usize); )*
                out
            }

            /// Each column's field name, in [`Self::columns`]' order (a
            /// named column once per variable).
            pub fn column_names(&self) -> Vec<&'static str> {
                let mut out = vec![];
                $( observations!(@name $kind, out, &self.$field, stringify!($field)); )*
                out
            }

            /// The field name of every column observations may have.
            pub const COLUMN_NAMES: &'static [&'static str] = &[$(stringify!($field)),*];

            /// Every column that has a file, in declaration order, with it.
            pub fn files(&self) -> Vec<(File, Column<'_, R>)> {
                vec![$( $( (
                    File { field: stringify!($field), name: $file, dims: &[$(Dim::$dim),*] },
                    observations!(@column $kind $elem, &self.$field),
                ), )? )*]
            }

            /// [`Self::files`], to fill.
            pub fn files_mut(&mut self) -> Vec<(File, ColumnMut<'_, R>)> {
                vec![$( $( (
                    File { field: stringify!($field), name: $file, dims: &[$(Dim::$dim),*] },
                    observations!(@column_mut $kind $elem, &mut self.$field),
                ), )? )*]
            }

            /// [`Self::columns`], to write.
            pub fn columns_mut(&mut self) -> Vec<(usize, ColMut<'_, R>)> {
                let s = self.widths();
                let mut out = vec![];
                $( observations!(@col_mut $kind $elem, out, &mut self.$field, s.$width as usize); )*
                out
            }

            /// The same observations in another precision.
            pub fn convert<S: Real>(&self) -> Observations<S> {
                Observations {
                    n: self.n,
                    frames: self.frames,
                    max_points: self.max_points,
                    exponents: self.exponents,
                    cycle_points: self.cycle_points,
                    $( $field: observations!(@cast $kind $elem, &self.$field), )*
                }
            }

            /// Views of every column, which must outlive the sink and not
            /// move meanwhile.
            pub fn sink(&mut self) -> Sink<R> {
                Sink { $( $field: observations!(@view $kind $elem, &mut self.$field), )* }
            }
        }

        /// Bytes of one trajectory's observations of `plan` in `precision`;
        /// `None` if they do not fit in 64 bits.
        pub fn bytes_per_trajectory(plan: &Plan, precision: Precision) -> Option<u64> {
            let s = Shape::of(plan)?;
            let real = precision.bytes() as u64;
            let mut total = STATUS_ON_DISK_EXTRA;
            if s.attractors {
                total += LABEL_ON_DISK;
            }
            $(
                if $(s.$when)&&+ {
                    let vars = observations!(@count $kind [$($list)?], plan);
                    let elem = observations!(@bytes $elem, real);
                    total = total.checked_add(vars.checked_mul(s.per.$width)?.checked_mul(elem)?)?;
                }
            )*
            Some(total)
        }
    };
    (@rows Named R) => { Vec<Rows<R>> };
    (@rows Plain $e:ident) => { Rows<$e> };
    (@alloc Named [$list:ident] R, $plan:expr, $len:expr, $when:expr) => {
        $plan.$list.iter().map(|v| (var_name($plan, *v), vec![R::nan(); $len])).collect()
    };
    (@alloc Plain [] $e:ident, $plan:expr, $len:expr, $when:expr) => {
        if $when { vec![observations!(@init $e); $len] } else { vec![] }
    };
    (@bare Named $e:ident, $n:expr, $($when:ident)&+) => { vec![] };
    (@bare Plain $e:ident, $n:expr, always) => { vec![observations!(@init $e); $n] };
    (@bare Plain $e:ident, $n:expr, $($when:ident)&+) => { vec![] };
    (@init R) => { R::nan() };
    (@init u32) => { 0u32 };
    (@init i32) => { -1i32 };
    (@col Named R, $out:expr, $v:expr, $w:expr) => {
        $out.extend($v.iter().map(|(_, x)| ($w, Col::Real(x.as_slice()))))
    };
    (@col Plain R, $out:expr, $v:expr, $w:expr) => { $out.push(($w, Col::Real($v.as_slice()))) };
    (@col Plain u32, $out:expr, $v:expr, $w:expr) => { $out.push(($w, Col::Count($v.as_slice()))) };
    (@col Plain i32, $out:expr, $v:expr, $w:expr) => { $out.push(($w, Col::Int($v.as_slice()))) };
    (@column Named R, $v:expr) => { Column::Named($v.as_slice()) };
    (@column Plain R, $v:expr) => { Column::Plain(Col::Real($v.as_slice())) };
    (@column Plain u32, $v:expr) => { Column::Plain(Col::Count($v.as_slice())) };
    (@column Plain i32, $v:expr) => { Column::Plain(Col::Int($v.as_slice())) };
    (@column_mut Named R, $v:expr) => { ColumnMut::Named($v) };
    (@column_mut Plain R, $v:expr) => { ColumnMut::Plain(ColMut::Real($v)) };
    (@column_mut Plain u32, $v:expr) => { ColumnMut::Plain(ColMut::Count($v)) };
    (@column_mut Plain i32, $v:expr) => { ColumnMut::Plain(ColMut::Int($v)) };
    (@name Named, $out:expr, $v:expr, $name:expr) => { $out.extend($v.iter().map(|_| $name)) };
    (@name Plain, $out:expr, $v:expr, $name:expr) => { $out.push($name) };
    (@col_mut Named R, $out:expr, $v:expr, $w:expr) => {
        $out.extend($v.iter_mut().map(|(_, x)| ($w, ColMut::Real(x.as_mut_slice()))))
    };
    (@col_mut Plain R, $out:expr, $v:expr, $w:expr) => {
        $out.push(($w, ColMut::Real($v.as_mut_slice())))
    };
    (@col_mut Plain u32, $out:expr, $v:expr, $w:expr) => {
        $out.push(($w, ColMut::Count($v.as_mut_slice())))
    };
    (@col_mut Plain i32, $out:expr, $v:expr, $w:expr) => {
        $out.push(($w, ColMut::Int($v.as_mut_slice())))
    };
    (@cast Named R, $v:expr) => { $v.iter().map(|(n, x)| (n.clone(), cast(x))).collect() };
    (@cast Plain R, $v:expr) => { cast($v) };
    (@cast Plain u32, $v:expr) => { $v.clone() };
    (@cast Plain i32, $v:expr) => { $v.clone() };
    (@view Named R, $v:expr) => { $v.iter_mut().map(|(_, x)| Rows::new(x)).collect() };
    (@view Plain $e:ident, $v:expr) => { Rows::new($v) };
    (@count Named [$list:ident], $plan:expr) => { $plan.$list.len() as u64 };
    (@count Plain [], $plan:expr) => { 1u64 };
    (@bytes R, $real:expr) => { $real };
    (@bytes u32, $real:expr) => { 4u64 };
    (@bytes i32, $real:expr) => { 4u64 };
}

observations! {
    /// `(variable, values[n])`; NaN for trajectories that did not finish.
    final_values: Named(final_vars) R, per one, when always, file "final" [];
    /// `(variable, values[n × frames])`, NaN after a trajectory stopped.
    trajectory: Named(trajectory_vars) R, per frames, when always, file "trajectory" [Frame];
    /// `(variable, values[n × max_points])`, NaN-padded.
    poincare: Named(poincare_vars) R, per max_points, when always, file "poincare" [Point];
    /// Points found per trajectory (may exceed `max_points`; only that many kept).
    poincare_count: Plain u32, per one, when points, file "poincare_count" [];
    /// Half the peak-to-peak range of the cycle variable over the measuring window.
    cycle_amplitude: Plain R, per one, when cycle, file "cycle_amplitude" [];
    /// Mean time between upward crossings of the cycle level in the window (NaN if fewer than two).
    cycle_period: Plain R, per one, when cycle, file "cycle_period" [];
    /// `(variable, means[n])`: each averaged variable's time average.
    mean: Named(average_vars) R, per one, when always, file "mean" [];
    /// Finite-time Lyapunov exponents, largest first (`exponents` per trajectory).
    lyapunov: Plain R, per exponents, when lyapunov, file "lyapunov" [Exponent];
    /// Fast Lyapunov Indicator: the largest ln‖w‖ over the samples.
    fli: Plain R, per one, when fli, file "fli" [];
    /// MEGNO ⟨Y⟩ at the last sample.
    megno: Plain R, per one, when megno, file "megno" [];
    /// SALI at the last sample.
    sali: Plain R, per one, when sali, file "sali" [];
    /// GALI_k at the last sample.
    gali: Plain R, per one, when gali, file "gali" [];
    /// The exponents so far at each trajectory frame (`frames × exponents`
    /// per trajectory; NaN before the first counted sample).
    trajectory_lyapunov: Plain R, per frame_exponents, when lyapunov & framed,
        file "trajectory_lyapunov" [Frame, Exponent];
    /// The FLI so far at each trajectory frame (NaN before the first sample).
    trajectory_fli: Plain R, per frames, when fli & framed, file "trajectory_fli" [Frame];
    /// ⟨Y⟩ so far at each trajectory frame (NaN before the first sample).
    trajectory_megno: Plain R, per frames, when megno & framed,
        file "trajectory_megno" [Frame];
    /// SALI at the last sample at each trajectory frame.
    trajectory_sali: Plain R, per frames, when sali & framed, file "trajectory_sali" [Frame];
    /// GALI_k at the last sample at each trajectory frame.
    trajectory_gali: Plain R, per frames, when gali & framed, file "trajectory_gali" [Frame];
    /// The period of the cycle each trajectory's samples end on (1: a fixed
    /// point), 0 aperiodic, −1 escaped (stopped or non-finite).
    attractor_period: Plain i32, per one, when attractors, file "attractor_period" [];
    /// The sample from which on they recur with that period (−1: none).
    transient: Plain i32, per one, when attractors, file "transient" [];
    /// `(variable, values[n × cycle_points])`: the last `max_period`
    /// samples, oldest first (NaN where fewer were taken).
    attractor_points: Named(attractor_vars) R, per cycle_points, when always,
        file "attractor_points" [Sample];
    /// 0: ok; k > 0: non-finite at step k.
    nonfinite_step: Plain u32, per one, when always;
    /// 0: not stopped; k > 0: stopped by the stop condition after step k.
    stop_step: Plain u32, per one, when always;
}

/// The status is written as `status.npy` (1 byte) and `status_step.npy` (8
/// bytes): 5 more than its 4 in memory.
const STATUS_ON_DISK_EXTRA: u64 = 5;

/// `attractor.npy`, written after the run: a label (4 bytes) per trajectory.
const LABEL_ON_DISK: u64 = 4;

/// A column holding one array per observed variable: `(variable, values)`.
pub type Named<R> = Vec<(String, Vec<R>)>;
/// A column holding one array.
pub type Plain<T> = Vec<T>;

/// One column of [`Observations`]: its values, some per trajectory.
#[derive(Debug)]
pub enum Col<'a, R> {
    Real(&'a [R]),
    Count(&'a [u32]),
    Int(&'a [i32]),
}

/// [`Col`], to write.
#[derive(Debug)]
pub enum ColMut<'a, R> {
    Real(&'a mut [R]),
    Count(&'a mut [u32]),
    Int(&'a mut [i32]),
}

impl<R> Col<'_, R> {
    pub fn is_empty(&self) -> bool {
        match self {
            Col::Real(v) => v.is_empty(),
            Col::Count(v) => v.is_empty(),
            Col::Int(v) => v.is_empty(),
        }
    }
}

impl<R> ColMut<'_, R> {
    pub fn is_empty(&self) -> bool {
        match self {
            ColMut::Real(v) => v.is_empty(),
            ColMut::Count(v) => v.is_empty(),
            ColMut::Int(v) => v.is_empty(),
        }
    }
}

/// How a column is written: `<name>.npy`, or for a named column
/// `<name>_<variable>.npy` per variable; `dims`: its dimensions after the
/// scene's axes (a vector variable adds `component`).
#[derive(Debug, Clone, Copy)]
pub struct File {
    /// The column's field in [`Observations`].
    pub field: &'static str,
    pub name: &'static str,
    pub dims: &'static [Dim],
}

impl File {
    /// The file of the column, or of its variable `var` (a named column).
    pub fn npy(&self, var: Option<&str>) -> String {
        match var {
            Some(v) => format!("{}_{v}.npy", self.name),
            None => format!("{}.npy", self.name),
        }
    }

    /// Its dimensions after the axes in `obs`: lengths and names.
    pub fn inner<R>(&self, obs: &Observations<R>) -> (Vec<u64>, Vec<&'static str>) {
        let lengths = self.dims.iter().map(|d| d.len(obs) as u64).collect();
        (lengths, self.dims.iter().map(|d| d.name()).collect())
    }
}

/// A dimension of a column after the scene's axes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dim {
    Frame,
    Point,
    Exponent,
    Sample,
}

impl Dim {
    /// Its name in the run's `dims` (what xarray labels it with).
    pub fn name(self) -> &'static str {
        match self {
            Dim::Frame => "frame",
            Dim::Point => "point",
            Dim::Exponent => "exponent",
            Dim::Sample => "sample",
        }
    }

    /// Its length in `obs`.
    pub fn len<R>(self, obs: &Observations<R>) -> usize {
        match self {
            Dim::Frame => obs.frames,
            Dim::Point => obs.max_points,
            Dim::Exponent => obs.exponents,
            Dim::Sample => obs.cycle_points,
        }
    }
}

/// A column of [`Observations`] with a file: one array per variable, or one.
#[derive(Debug)]
pub enum Column<'a, R> {
    Named(&'a [(String, Vec<R>)]),
    Plain(Col<'a, R>),
}

/// [`Column`], to fill.
#[derive(Debug)]
pub enum ColumnMut<'a, R> {
    Named(&'a mut Named<R>),
    Plain(ColMut<'a, R>),
}

/// What a plan's observations hold per trajectory, and which columns.
struct Shape {
    n: usize,
    per: Widths,
    always: bool,
    points: bool,
    cycle: bool,
    lyapunov: bool,
    fli: bool,
    megno: bool,
    sali: bool,
    gali: bool,
    attractors: bool,
    /// Trajectory frames: the indicators' running values are kept per frame.
    framed: bool,
}

/// How many values each trajectory has in a column.
struct Widths {
    one: u64,
    frames: u64,
    max_points: u64,
    exponents: u64,
    /// The exponents at each trajectory frame.
    frame_exponents: u64,
    /// The attractor detector's last samples.
    cycle_points: u64,
}

impl Shape {
    /// `None` if the frames per trajectory overflow.
    fn of(plan: &Plan) -> Option<Shape> {
        let max_points = plan.observers.poincare.as_ref().map_or(0, |p| p.max_points) as u64;
        let frames = frames_per_trajectory(plan)?;
        let exponents = plan.indicators.as_ref().map_or(0, |i| i.exponents()) as u64;
        let o = &plan.observers;
        Some(Shape {
            n: plan.n,
            per: Widths {
                one: 1,
                frames,
                max_points,
                exponents,
                frame_exponents: frames.checked_mul(exponents)?,
                cycle_points: o.attractors.as_ref().map_or(0, |a| a.max_period) as u64,
            },
            always: true,
            points: max_points > 0,
            cycle: plan.cycle_var.is_some(),
            lyapunov: o.lyapunov.is_some(),
            fli: o.fli.is_some(),
            megno: o.megno.is_some(),
            sali: o.sali.is_some(),
            gali: o.gali.is_some(),
            attractors: o.attractors.is_some(),
            framed: frames > 0,
        })
    }
}

impl<R> Sink<R> {
    /// The indicators' columns: the exponents', then those of
    /// `indicators::SCALAR_INDICATORS` in its order; `framed`: their running
    /// values at each trajectory frame.
    pub fn indicators(&self, framed: bool) -> (&Rows<R>, [&Rows<R>; 4]) {
        match framed {
            false => (
                &self.lyapunov,
                [&self.fli, &self.megno, &self.sali, &self.gali],
            ),
            true => (
                &self.trajectory_lyapunov,
                [
                    &self.trajectory_fli,
                    &self.trajectory_megno,
                    &self.trajectory_sali,
                    &self.trajectory_gali,
                ],
            ),
        }
    }
}

/// Raw view of an output array that blocks fill in disjoint rows.
pub struct Rows<T> {
    ptr: *mut T,
    len: usize,
}
unsafe impl<T: Send> Sync for Rows<T> {}
unsafe impl<T: Send> Send for Rows<T> {}

impl<T> Rows<T> {
    fn new(v: &mut [T]) -> Self {
        Rows {
            ptr: v.as_mut_ptr(),
            len: v.len(),
        }
    }
    /// SAFETY: callers write each index from one block only (rows of distinct
    /// trajectories), and the vector outlives the run.
    #[inline]
    pub fn set(&self, i: usize, v: T) {
        assert!(i < self.len);
        unsafe { *self.ptr.add(i) = v }
    }
}

/// A column one trajectory's values are written into: the CPU's rows of a
/// sink, or the observations themselves. Empty where the plan lacks it.
pub trait Put<R> {
    fn is_empty(&self) -> bool;
    fn put(&mut self, i: usize, v: R);
}

impl<R> Put<R> for &Rows<R> {
    fn is_empty(&self) -> bool {
        self.len == 0
    }
    fn put(&mut self, i: usize, v: R) {
        self.set(i, v)
    }
}

impl<R> Put<R> for &mut Vec<R> {
    fn is_empty(&self) -> bool {
        self.as_slice().is_empty()
    }
    fn put(&mut self, i: usize, v: R) {
        self[i] = v
    }
}

fn var_name(plan: &Plan, v: ObsVar) -> String {
    match v {
        ObsVar::State(k) => plan.vars[k].to_string(),
        ObsVar::Time => "t".to_string(),
    }
}

/// `v` in another precision.
fn cast<R: Real, S: Real>(v: &[R]) -> Vec<S> {
    v.iter().map(|x| S::from_f64(x.to_f64())).collect()
}

impl<R: Real> Observations<R> {
    /// Arrays for `plan`, filled with NaN (counts and status with 0).
    ///
    /// Panics if an array's length overflows `usize`; [`Self::try_for_plan`]
    /// says so instead. The backends are reached through
    /// [`crate::plan::size::output_gate`] or [`Self::lengths`], which refuse
    /// such plans first.
    pub fn for_plan(plan: &Plan) -> Self {
        Self::try_for_plan(plan).unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Self::for_plan`], or why its arrays cannot be sized.
    pub fn try_for_plan(plan: &Plan) -> Result<Self, String> {
        Self::lengths(plan)?;
        let shape = Shape::of(plan).ok_or("the trajectory frames per trajectory overflow")?;
        Ok(Self::allocate(plan, &shape))
    }

    /// The widths these observations were sized for.
    fn widths(&self) -> Widths {
        Widths {
            one: 1,
            frames: self.frames as u64,
            max_points: self.max_points as u64,
            exponents: self.exponents as u64,
            frame_exponents: (self.frames * self.exponents) as u64,
            cycle_points: self.cycle_points as u64,
        }
    }

    /// The columns of `indicators::SCALAR_INDICATORS`, in its order (a column
    /// the plan lacks is empty); `framed`: their running values at each
    /// trajectory frame.
    pub fn scalar_indicators(&self, framed: bool) -> [&[R]; 4] {
        match framed {
            false => [&self.fli, &self.megno, &self.sali, &self.gali],
            true => [
                &self.trajectory_fli,
                &self.trajectory_megno,
                &self.trajectory_sali,
                &self.trajectory_gali,
            ],
        }
    }

    /// Every column with values per trajectory frame (the frames, the
    /// indicators' running values), with how many values each frame has.
    pub fn framed_columns_mut(&mut self) -> Vec<(&mut [R], usize)> {
        let exponents = self.exponents;
        let mut out = vec![];
        for (file, column) in self.files_mut() {
            if file.dims.first() != Some(&Dim::Frame) {
                continue;
            }
            let width = match file.dims.contains(&Dim::Exponent) {
                true => exponents,
                false => 1,
            };
            match column {
                ColumnMut::Named(v) => out.extend(v.iter_mut().map(|(_, x)| (&mut x[..], width))),
                ColumnMut::Plain(ColMut::Real(x)) => out.push((x, width)),
                ColumnMut::Plain(ColMut::Count(_) | ColMut::Int(_)) => {}
            }
        }
        out
    }

    /// [`Sink::indicators`]' columns, to fill.
    pub fn indicators_mut(&mut self, framed: bool) -> (&mut Vec<R>, [&mut Vec<R>; 4]) {
        match framed {
            false => (
                &mut self.lyapunov,
                [
                    &mut self.fli,
                    &mut self.megno,
                    &mut self.sali,
                    &mut self.gali,
                ],
            ),
            true => (
                &mut self.trajectory_lyapunov,
                [
                    &mut self.trajectory_fli,
                    &mut self.trajectory_megno,
                    &mut self.trajectory_sali,
                    &mut self.trajectory_gali,
                ],
            ),
        }
    }

    /// The lengths of the arrays of `plan`, counted with checked arithmetic
    /// (nothing is allocated).
    pub fn lengths(plan: &Plan) -> Result<Lengths, String> {
        let n = plan.n;
        let frames = frames_per_trajectory(plan)
            .and_then(|f| usize::try_from(f).ok())
            .ok_or("the trajectory frames per trajectory do not fit in 64 bits")?;
        let max_points = plan.observers.poincare.as_ref().map_or(0, |p| p.max_points);
        let too_many = |what: &str, per: usize| {
            format!("{n} trajectories × {per} {what} do not fit in 64 bits: record less (a larger output.trajectory.every, a smaller output.poincare.max_points) or use fewer values along an axis")
        };
        Ok(Lengths {
            n,
            frames,
            max_points,
            trajectory: n
                .checked_mul(frames)
                .ok_or_else(|| too_many("trajectory frames", frames))?,
            poincare: n
                .checked_mul(max_points)
                .ok_or_else(|| too_many("Poincaré points", max_points))?,
        })
    }

    /// Copies the rows of `src` (a sub-run's) to rows `rows` of `self` (the
    /// whole scene's); a sub-run of fewer steps fills the leading frames.
    pub fn place_rows(&mut self, src: &Observations<R>, rows: impl Iterator<Item = usize>) {
        let rows: Vec<usize> = rows.collect();
        for ((wd, dst), (ws, from)) in self.columns_mut().into_iter().zip(src.columns()) {
            match (dst, from) {
                (ColMut::Real(d), Col::Real(s)) => place(d, wd, s, ws, &rows),
                (ColMut::Count(d), Col::Count(s)) => place(d, wd, s, ws, &rows),
                (ColMut::Int(d), Col::Int(s)) => place(d, wd, s, ws, &rows),
                _ => unreachable!("observations of one plan have the same columns"),
            }
        }
    }

    pub fn status(&self, i: usize) -> Status {
        match (self.nonfinite_step[i], self.stop_step[i]) {
            (0, 0) => Status::Ok,
            (0, step) => Status::Stopped { step: step.into() },
            (step, _) => Status::NonFinite { step: step.into() },
        }
    }

    /// Number of trajectories that ran to the end with a finite state.
    pub fn count_ok(&self) -> usize {
        (0..self.n)
            .filter(|i| self.status(*i) == Status::Ok)
            .count()
    }

    /// Number of trajectories the stop condition stopped.
    pub fn count_stopped(&self) -> usize {
        self.stop_step.iter().filter(|s| **s != 0).count()
    }

    pub fn final_of(&self, var: &str) -> Option<&[R]> {
        self.final_values
            .iter()
            .find(|(v, _)| v == var)
            .map(|(_, x)| x.as_slice())
    }

    pub fn trajectory_of(&self, var: &str) -> Option<&[R]> {
        self.trajectory
            .iter()
            .find(|(v, _)| v == var)
            .map(|(_, x)| x.as_slice())
    }

    pub fn mean_of(&self, var: &str) -> Option<&[R]> {
        self.mean
            .iter()
            .find(|(v, _)| v == var)
            .map(|(_, x)| x.as_slice())
    }

    pub fn poincare_of(&self, var: &str) -> Option<&[R]> {
        self.poincare
            .iter()
            .find(|(v, _)| v == var)
            .map(|(_, x)| x.as_slice())
    }
}

/// The lengths of the arrays of a plan's [`Observations`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Lengths {
    /// Trajectories (the length of the per-trajectory arrays).
    pub n: usize,
    /// Frames per trajectory, and the length of each trajectory array.
    pub frames: usize,
    pub trajectory: usize,
    /// Points kept per trajectory, and the length of each Poincaré array.
    pub max_points: usize,
    pub poincare: usize,
}

/// Trajectory frames per trajectory (every `every` steps from step 0);
/// `None` if the count overflows.
pub fn frames_per_trajectory(plan: &Plan) -> Option<u64> {
    match &plan.observers.trajectory {
        Some(t) => (plan.steps / t.every).checked_add(1),
        None => Some(0),
    }
}

/// Bytes the observations of `plan` take in `precision`, before running;
/// `None` if they do not fit in 64 bits (every count is checked).
pub fn estimate_bytes(plan: &Plan, precision: Precision) -> Option<u64> {
    (plan.n as u64).checked_mul(bytes_per_trajectory(plan, precision)?)
}

/// Row `j` of `src` (`ws` values each) to row `rows[j]` of `dst` (`wd`
/// each, `wd ≥ ws`: the leading values); an empty `src` copies nothing.
fn place<T: Copy>(dst: &mut [T], wd: usize, src: &[T], ws: usize, rows: &[usize]) {
    if src.is_empty() {
        return;
    }
    for (j, g) in rows.iter().enumerate() {
        dst[g * wd..g * wd + ws].copy_from_slice(&src[j * ws..(j + 1) * ws]);
    }
}
