// reeb driver: one invocation integrates one or several trajectories over
// the window of steps [u.step0, u.step0 + u.nsteps). crates/reeb-backend/src/backend/gpu/codegen.rs splices the
// plan's code in at the `{{...}}` markers: the inputs (constants, or values
// looked up along the ensemble's axes), the step (the plan's ops as calls of
// the shared functions), the finite test and the observers.

// Keep in sync with `struct Uniforms` of crates/reeb-backend/src/backend/gpu/run.rs.
struct Uniforms {
    // Grid index of the chunk's first trajectory (the plan's first row included).
    base: u32,
    // Trajectories in the chunk, and the stride of the per-trajectory arrays.
    count: u32,
    cap: u32,
    // The window of steps of this dispatch.
    step0: u32,
    nsteps: u32,
    // First trajectory frame that traj_out holds, and how many it holds.
    frame0: u32,
    nframes: u32,
    _pad: u32,
}

@group(0) @binding(0) var<uniform> u: Uniforms;
// Integrated variables: state[k * cap + i].
@group(0) @binding(1) var<storage, read_write> state: array<R>;
// Input values along the axes.
@group(0) @binding(2) var<storage, read> table: array<R>;
// 0: running; k > 0: non-finite at step k (the trajectory stopped there);
// crates/reeb-core/src/plan/slots.rs has the other words (stopped, cut).
@group(0) @binding(3) var<storage, read_write> status: array<u32>;
// Observer state that lives across dispatches.
@group(0) @binding(4) var<storage, read_write> aux_r: array<R>;
@group(0) @binding(5) var<storage, read_write> aux_u: array<u32>;
// Trajectory frames of this window: traj_out[(frame * vars + j) * cap + i].
@group(0) @binding(6) var<storage, read_write> traj_out: array<R>;
// Poincaré points: points_out[(k * vars + j) * cap + i].
@group(0) @binding(7) var<storage, read_write> points_out: array<R>;
// Time terms the ensemble shares, per step and stage of this window (only in
// kernels whose plan shares them; crates/reeb-backend/src/backend/gpu/time_table.rs).
{{TIME_TABLE}}

// The launch (crates/reeb-backend/src/backend/gpu/tuning.rs): {{WORKGROUP}} invocations per
// workgroup, each integrating {{PER_THREAD}} trajectories, thread + k·threads,
// so that neighbouring invocations read neighbouring trajectories.
@compute @workgroup_size({{WORKGROUP}})
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(num_workgroups) nwg: vec3<u32>,
        @builtin(local_invocation_index) li: u32) {
    let thread = (wg.y * nwg.x + wg.x) * {{WORKGROUP}}u + li;
    let threads = nwg.x * nwg.y * {{WORKGROUP}}u;
    for (var k = 0u; k < {{PER_THREAD}}u; k = k + 1u) {
        trajectory(thread + k * threads);
    }
}

// One trajectory over the window.
fn trajectory(i: u32) {
    if i >= u.count {
        return;
    }
    if status[i] != 0u {
        return;
    }
    let g = u.base + i;
{{INPUTS}}
{{LOAD}}
    var st: u32 = 0u;
{{BEGIN}}
    var n: u32 = u.step0;
{{BLOCKS}}
    loop {
        if n >= u.step0 + u.nsteps {
            break;
        }
        let nf: R = R(n);
{{STEP}}
        if !({{FINITE}}) {
            st = n + 1u;
            break;
        }
{{OBSERVE}}
        n = n + 1u;
    }
    // A loop the adapter ended early (llvmpipe's limit on loop iterations,
    // crates/reeb-backend/src/backend/gpu/run.rs) is flagged, never a silently short window.
    if st == 0u && n < u.step0 + u.nsteps {
        st = {{CUT}}u;
    }
{{STORE}}
    status[i] = st;
}
