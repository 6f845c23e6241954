//! `reeb slurm`: a run in shards as a Slurm job array whose task K runs
//! `reeb run … --shard K/N --resume` (a requeued or restarted task resumes
//! its chunks), and `reeb merge` as a job that waits for the whole array
//! (`--dependency=afterok`). The scripts and the tasks' logs go into
//! `DIR.slurm/`; the run itself into `DIR.partial`, then `DIR`. The
//! scripts replace only scripts reeb wrote there (`owned.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};

use crate::output::owned::Owned;

/// The batch scripts in `DIR.slurm/`: the job array, and the merge after it.
const SHARDS: &str = "shards.sbatch";
const MERGE: &str = "merge.sbatch";

/// What `reeb slurm` was asked for.
pub struct SlurmOptions {
    pub shards: usize,
    pub out: PathBuf,
    pub partition: Option<String>,
    pub gpus_per_task: Option<u32>,
    pub time: Option<String>,
    pub dry_run: bool,
    /// Options of `reeb run` every task passes on (`--backend gpu`, …).
    pub run_args: Vec<String>,
}

/// The jobs written (and submitted unless a dry run).
pub struct Jobs {
    pub dir: PathBuf,
    pub array_id: Option<String>,
    pub merge_id: Option<String>,
    pub line: String,
}

/// Writes the batch scripts for `scene` and submits them with `sbatch`.
pub fn submit(scene: &Path, name: &str, o: &SlurmOptions) -> Result<Jobs> {
    check(o)?;
    let abs = |p: &Path| std::path::absolute(p).with_context(|| format!("{}", p.display()));
    let (scene, out) = (abs(scene)?, abs(&o.out)?);
    let reeb = std::env::current_exe().context("the path of this reeb")?;
    script_safe("the scene file's path", &scene)?;
    script_safe("--out", &out)?;
    script_safe("the path of this reeb", &reeb)?;
    let mut dir = out.clone().into_os_string();
    dir.push(".slurm");
    let dir = PathBuf::from(dir);
    if let Some(parent) = dir.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let mut folder = Owned::claim(&dir, &[SHARDS, MERGE], &["logs"])?;
    let array = folder.write(SHARDS, &array_script(&reeb, &scene, &out, &dir, name, o))?;
    let merge = folder.write(MERGE, &merge_script(&reeb, &out, &dir, name, o))?;
    if o.dry_run {
        let line = format!(
            "wrote {} and {}; submit with: sbatch --parsable {} and then sbatch --dependency=afterok:<its id> {}",
            array.display(),
            merge.display(),
            quote(&array.display().to_string()),
            quote(&merge.display().to_string())
        );
        return Ok(Jobs {
            dir,
            array_id: None,
            merge_id: None,
            line,
        });
    }
    let array_id = sbatch(&[], &array)?;
    let merge_id = sbatch(&[format!("--dependency=afterok:{array_id}")], &merge)?;
    let line = format!(
        "submitted job array {array_id} ({} shards) and merge job {merge_id} (after the array succeeds) → {}; logs in {}",
        o.shards,
        out.display(),
        dir.join("logs").display()
    );
    Ok(Jobs {
        dir,
        array_id: Some(array_id),
        merge_id: Some(merge_id),
        line,
    })
}

/// Refuses options that would write a broken script, naming the flag.
fn check(o: &SlurmOptions) -> Result<()> {
    if o.shards == 0 {
        bail!("--shards: at least 1");
    }
    if let Some(p) = &o.partition {
        if p.is_empty()
            || !p
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "_-.,".contains(c))
        {
            bail!("--partition: `{p}` is not a partition name (letters, digits, _ - . ,)");
        }
    }
    if let Some(t) = &o.time {
        if t.is_empty()
            || !t
                .chars()
                .all(|c| c.is_ascii_digit() || c == ':' || c == '-')
        {
            bail!("--time: `{t}` is not a Slurm time (minutes, HH:MM:SS or D-HH:MM:SS)");
        }
    }
    if o.gpus_per_task == Some(0) {
        bail!("--gpus-per-task: at least 1 (leave it out for CPU tasks)");
    }
    Ok(())
}

/// Refuses a path that a script cannot carry safely: control characters
/// (a newline would end the `#SBATCH` line or comment it sits in, and the
/// rest would run as a command) and backslashes (Slurm reads one in an
/// `--output` path as "no replacement symbols", so `%a` would stay as is).
/// Everything else is quoted where it is written.
fn script_safe(field: &str, path: &Path) -> Result<()> {
    let Some(text) = path.to_str() else {
        bail!(
            "{field}: {:?} is not valid UTF-8, which a Slurm batch script cannot carry faithfully; choose another path",
            path.display().to_string()
        );
    };
    if let Some(c) = text.chars().find(|c| c.is_control() || *c == '\\') {
        bail!(
            "{field}: {:?} holds the character {:?}, which a Slurm batch script cannot carry safely; choose a path without control characters or backslashes",
            path.display().to_string(),
            c
        );
    }
    Ok(())
}

/// `path` as the value of an `#SBATCH` option: in double quotes (Slurm
/// groups a quoted value, spaces and `#` included), `"` escaped with a
/// backslash, and `%` doubled (Slurm's filename patterns read `%%` as `%`);
/// `pattern` is appended as is (`%a`: the array index).
fn sbatch_path(path: &Path, pattern: &str) -> String {
    let text = path.display().to_string();
    let escaped = text.replace('"', "\\\"").replace('%', "%%");
    format!("\"{escaped}{pattern}\"")
}

/// `#SBATCH` lines every job of the run shares.
fn common(name: &str, o: &SlurmOptions) -> String {
    let mut s = format!(
        "#SBATCH --job-name={}\n#SBATCH --ntasks=1\n",
        job_name(name)
    );
    if let Some(p) = &o.partition {
        s += &format!("#SBATCH --partition={p}\n");
    }
    if let Some(t) = &o.time {
        s += &format!("#SBATCH --time={t}\n");
    }
    s
}

/// A job name Slurm shows as is: the scene's name, plain.
fn job_name(name: &str) -> String {
    let plain: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("reeb-{plain}")
}

fn array_script(
    reeb: &Path,
    scene: &Path,
    out: &Path,
    dir: &Path,
    name: &str,
    o: &SlurmOptions,
) -> String {
    let mut s = format!(
        "#!/bin/bash\n# reeb slurm: shard $SLURM_ARRAY_TASK_ID of {n} of {scene}.\n# A requeued or restarted task resumes (--resume): finished chunks are kept.\n",
        n = o.shards,
        scene = scene.display()
    );
    s += &common(name, o);
    s += &format!(
        "#SBATCH --array=0-{}\n#SBATCH --requeue\n#SBATCH --open-mode=append\n#SBATCH --output={}\n",
        o.shards - 1,
        sbatch_path(&dir.join("logs"), "/shard-%a.out")
    );
    if let Some(g) = o.gpus_per_task {
        s += &format!("#SBATCH --gpus-per-task={g}\n");
    }
    let extra: String = o
        .run_args
        .iter()
        .map(|a| format!(" {}", quote(a)))
        .collect();
    s += &format!(
        "echo \"reeb shard $SLURM_ARRAY_TASK_ID/{n} on $(hostname), attempt ${{SLURM_RESTART_COUNT:-0}}\"\nexec {reeb} run {scene} --out {out} --shard \"$SLURM_ARRAY_TASK_ID/{n}\" --resume{extra}\n",
        n = o.shards,
        reeb = quote(&reeb.display().to_string()),
        scene = quote(&scene.display().to_string()),
        out = quote(&out.display().to_string()),
    );
    s
}

fn merge_script(reeb: &Path, out: &Path, dir: &Path, name: &str, o: &SlurmOptions) -> String {
    let mut s = "#!/bin/bash\n# reeb slurm: the merge, after every shard succeeded.\n".to_string();
    s += &common(name, o);
    s += &format!(
        "#SBATCH --output={}\nexec {} merge {}\n",
        sbatch_path(&dir.join("logs"), "/merge.out"),
        quote(&reeb.display().to_string()),
        quote(&out.display().to_string())
    );
    s
}

/// `s` as one shell word.
fn quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}

/// Submits `script` with `args`; returns the job id.
fn sbatch(args: &[String], script: &Path) -> Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .args(args)
        .arg(script)
        .output()
        .map_err(|e| {
            anyhow::anyhow!(
                "sbatch could not be run ({e}): is this a Slurm login node? --dry-run writes the scripts without submitting them"
            )
        })?;
    if !out.status.success() {
        bail!(
            "sbatch {} refused the job: {}",
            script.display(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    // `--parsable` prints "id" or "id;cluster".
    let id = text.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() {
        bail!("sbatch {} printed no job id", script.display());
    }
    Ok(id)
}
