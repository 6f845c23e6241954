//! A full disk (issue 31, point 4), on a small tmpfs mounted in a mount
//! namespace of the test's own (`unshare -r -m`: no root needed where user
//! namespaces are allowed, nothing to clean up): a checkpoint that does not
//! fit is skipped with a warning and the run goes on; and `--resume` needs
//! room only for what is left to write.
//!
//! Without `unshare` (or user namespaces) the tests print SKIP, unless
//! `REEB_REQUIRE_TMPFS=1` (CI).

use std::path::Path;
use std::process::Command;

use crate::common;

use common::runs::{ok, s, REEB};

/// Runs `script` in bash inside a mount namespace of its own, where
/// `$DISK` is a tmpfs of `size`; `None` (SKIP) where that cannot be had.
fn on_small_disk(dir: &Path, size: &str, script: &str) -> Option<(bool, String)> {
    let disk = dir.join("disk");
    std::fs::create_dir_all(&disk).unwrap();
    let whole =
        format!("set -u\nmount -t tmpfs -o size={size} tmpfs \"$DISK\" || exit 99\n{script}");
    let o = Command::new("unshare")
        .args(["-r", "-m", "bash", "-c", &whole])
        .env("DISK", &disk)
        .env("REEB", REEB)
        .output();
    let o = match o {
        Ok(o) if o.status.code() != Some(99) && !mount_refused(&o) => o,
        other => {
            let why = match other {
                Ok(o) => String::from_utf8_lossy(&o.stderr).into_owned(),
                Err(e) => e.to_string(),
            };
            assert!(
                std::env::var_os("REEB_REQUIRE_TMPFS").is_none(),
                "REEB_REQUIRE_TMPFS is set but no tmpfs could be mounted: {why}"
            );
            eprintln!("SKIP: no tmpfs in a mount namespace ({why})");
            return None;
        }
    };
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    Some((o.status.success(), text))
}

fn mount_refused(o: &std::process::Output) -> bool {
    let err = String::from_utf8_lossy(&o.stderr);
    err.starts_with("unshare:")
}

/// A van der Pol grid of 10⁵ trajectories, one chunk, `steps` steps, final
/// `q` and `frames` + 1 frames of `q`, f64.
fn scene(dir: &Path, steps: u64, frames: u64) -> std::path::PathBuf {
    let text = format!(
        r#"model = "van_der_pol"
[params]
epsilon = {{ linspace = [0.5, 2.0, 100] }}
[initial]
q = {{ linspace = [0.5, 2.5, 1000] }}
[integrator]
scheme = "s2"
dt = 0.01
steps = {steps}
[output]
final = ["q"]
trajectory = {{ every = {}, vars = ["q"] }}
[run]
backend = "cpu"
precision = "f64"
"#,
        steps / frames
    );
    let path = dir.join("big.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_checkpoint_that_does_not_fit_is_skipped_and_the_run_goes_on() {
    let d = common::runs::tmp("disk-full", "checkpoint");
    // A few seconds of work, a checkpoint of about 4 MB every 0.05 s.
    let scene = scene(&d, 30_000, 2);
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    // The disk fills up once the first checkpoint is written, and is
    // freed again once a checkpoint has failed.
    let script = format!(
        r#"log="$DISK/../run.log"
"$REEB" run {scene} --out "$DISK/run" --checkpoint-every 0.05 2> "$log" &
pid=$!
while [ ! -e "$DISK/run.partial/.reeb-chunks/0.state" ]; do kill -0 $pid || exit 1; sleep 0.01; done
# The run writes on meanwhile: a filler sized from a free space it has
# since taken fails, and is sized again.
until fallocate -l $(( $(df -B1 --output=avail "$DISK" | tail -1) - 65536 )) "$DISK/filler" 2>/dev/null; do
  rm -f "$DISK/filler"; kill -0 $pid || exit 1; sleep 0.01
done
while ! grep -q "checkpoint was not written" "$log"; do kill -0 $pid || break; sleep 0.01; done
rm "$DISK/filler"
wait $pid || {{ cat "$log"; exit 1; }}
cat "$log"
cp -r "$DISK/run" {copy}"#,
        scene = s(&scene),
        copy = s(&d.join("copy"))
    );
    let Some((ok, text)) = on_small_disk(&d, "32m", &script) else {
        return;
    };
    assert!(ok, "{text}");
    let warned = text.matches("checkpoint was not written").count();
    assert!(
        warned == 1 && text.contains("No space left on device"),
        "{text}"
    );
    same_arrays_of(&one, &d.join("copy"));
}

/// The arrays of two runs of [`scene`], byte for byte.
fn same_arrays_of(a: &Path, b: &Path) {
    for f in [
        "final_q.npy",
        "trajectory_q.npy",
        "status.npy",
        "status_step.npy",
    ] {
        let (x, y) = (std::fs::read(a.join(f)), std::fs::read(b.join(f)));
        assert!(x.is_ok() && x.ok() == y.ok(), "{f} differs");
    }
}

#[test]
fn resume_needs_room_only_for_what_is_left() {
    let d = common::runs::tmp("disk-full", "resume");
    // 10 frames: about 9.7 MB of arrays in 4 chunks.
    let scene = scene(&d, 6000, 10);
    let one = d.join("one");
    ok(&["run", s(&scene), "--out", s(&one)]);
    let script = format!(
        r#"run() {{ "$REEB" run {scene} --out "$DISK/run" --chunk-trajectories 25000 --checkpoint-every 0 "$@"; }}
run --shard 0/2 || exit 1
# Leave 7 MiB free: more than the half still to write, less than the whole.
avail=$(df -B1 --output=avail "$DISK" | tail -1)
fallocate -l $((avail - 7 * 1024 * 1024)) "$DISK/filler" || exit 1
run --resume || exit 1
cp -r "$DISK/run" {copy}"#,
        scene = s(&scene),
        copy = s(&d.join("copy"))
    );
    let Some((ok, text)) = on_small_disk(&d, "16m", &script) else {
        return;
    };
    assert!(ok, "{text}");
    assert!(text.contains("resuming: 2 of the 4 chunks"), "{text}");
    same_arrays_of(&one, &d.join("copy"));
}
