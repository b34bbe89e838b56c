//! Slurm, the existing engine: `wavetrace slurm` writes job scripts, submits them with
//! `sbatch` (a job array of parts and a merge job that waits for it, or a job array of frame
//! chunks) and, with `--wait`, polls `scontrol show job` until the jobs end. It calls the
//! Slurm commands as a user would; nothing of ours runs beside them.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// A failure talking to Slurm, or a job that failed: the message names the job and its log.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct SlurmError(pub String);

/// How the work is cut into array tasks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// One frame in `n` parts, one task each, then a merge job.
    Parts(u32),
    /// Frames `first..=last` every `step`, `per_task` frames per task.
    Frames {
        /// First frame.
        first: u32,
        /// Last frame (included when the step lands on it).
        last: u32,
        /// Frame step, at least 1.
        step: u32,
        /// Frames per array task, at least 1.
        per_task: u32,
    },
}

impl Split {
    /// Array tasks of the split.
    pub fn task_count(&self) -> u32 {
        match *self {
            Split::Parts(n) => n,
            Split::Frames {
                first,
                last,
                step,
                per_task,
            } => ((last - first) / step + 1).div_ceil(per_task),
        }
    }
}

/// Parses `A-B[:STEP]` (Blender's frame range with an optional step): `A <= B`, `STEP >= 1`.
pub fn parse_frame_range(text: &str) -> Result<(u32, u32, u32), String> {
    let usage = || format!("expected A-B or A-B:STEP with A <= B and STEP >= 1, got '{text}'");
    let (range, step) = match text.split_once(':') {
        Some((range, step)) => (range, step.parse::<u32>().map_err(|_| usage())?),
        None => (text, 1),
    };
    let (first, last) = range.split_once('-').ok_or_else(usage)?;
    let first: u32 = first.parse().map_err(|_| usage())?;
    let last: u32 = last.parse().map_err(|_| usage())?;
    if first > last || step == 0 {
        return Err(usage());
    }
    Ok((first, last, step))
}

/// Everything a submission needs; every path absolute.
#[derive(Clone, Debug)]
pub struct Submission {
    /// The wavetrace binary the jobs run (the running one).
    pub program: PathBuf,
    /// The scene file.
    pub scene: PathBuf,
    /// Render flags passed through to `wavetrace render` as given.
    pub render_flags: Vec<String>,
    /// The image (parts), or the image name with a `#` run (frames).
    pub output: PathBuf,
    /// How the work is cut.
    pub split: Split,
    /// Extra `sbatch` arguments, after ours (so they win): partition, time limit, account...
    pub sbatch_args: Vec<String>,
    /// The directory the jobs start in (the submitting shell's), for relative paths in flags.
    pub workdir: PathBuf,
}

impl Submission {
    /// The folder next to the output that holds the job scripts, the logs and the parts:
    /// `OUT.slurm`.
    pub fn folder(&self) -> PathBuf {
        let name = self
            .output
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| "wavetrace".into());
        self.output.with_file_name(format!("{name}.slurm"))
    }

    /// Part `k`'s file.
    pub fn part_path(&self, k: u32) -> PathBuf {
        self.folder().join(format!("part-{k}.wtpart"))
    }

    /// The log of array task `k` (Slurm's `%a`).
    pub fn task_log(&self, k: &str) -> PathBuf {
        self.folder().join(format!("task-{k}.log"))
    }

    /// The merge job's log.
    pub fn merge_log(&self) -> PathBuf {
        self.folder().join("merge.log")
    }

    /// The job name: `wavetrace-` and the scene's file stem.
    fn job_name(&self) -> String {
        let stem = self
            .scene
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        format!("wavetrace-{stem}")
    }

    /// The array task's script: renders its part, or its chunk of frames.
    pub fn array_script(&self) -> String {
        let program = shell_quote(&self.program.to_string_lossy());
        let mut render = format!(
            "exec {program} render {}",
            shell_quote(&self.scene.to_string_lossy())
        );
        for flag in &self.render_flags {
            render += " ";
            render += &shell_quote(flag);
        }
        let task = "${SLURM_ARRAY_TASK_ID:?this script runs as a Slurm array task}";
        let body = match self.split {
            Split::Parts(n) => {
                let part = shell_quote(&self.folder().join("part-").to_string_lossy());
                format!("{render} --part \"{task}/{n}\" -o {part}\"{task}.wtpart\"\n")
            }
            Split::Frames {
                first,
                last,
                step,
                per_task,
            } => format!(
                "first=$(({first} + {task} * {per_task} * {step}))\n\
                 last=$((first + {} * {step}))\n\
                 if [ \"$last\" -gt {last} ]; then last={last}; fi\n\
                 {render} --frames \"$first-$last:{step}\" -o {}\n",
                per_task - 1,
                shell_quote(&self.output.to_string_lossy())
            ),
        };
        format!(
            "#!/bin/sh\n# Written by `wavetrace slurm`: one task of the job array (see docs/farm.md).\n\
             set -eu\n{body}"
        )
    }

    /// The merge job's script (parts only).
    pub fn merge_script(&self) -> String {
        let n = self.split.task_count();
        let mut command = format!(
            "exec {} merge --quiet",
            shell_quote(&self.program.to_string_lossy())
        );
        for k in 0..n {
            command += " ";
            command += &shell_quote(&self.part_path(k).to_string_lossy());
        }
        command += " -o ";
        command += &shell_quote(&self.output.to_string_lossy());
        format!(
            "#!/bin/sh\n# Written by `wavetrace slurm`: merges the parts once every array task \
             succeeded.\nset -eu\n{command}\n"
        )
    }
}

/// `text` in single quotes for `sh`.
pub fn shell_quote(text: &str) -> String {
    format!("'{}'", text.replace('\'', "'\\''"))
}

/// Jobs submitted: the array and, for parts, the merge job.
#[derive(Clone, Debug)]
pub struct SubmittedJobs {
    /// The job array's id.
    pub array: String,
    /// The merge job's id.
    pub merge: Option<String>,
}

/// Writes the scripts into [`Submission::folder`] and submits them with `sbatch`. If the merge
/// job is refused, the array is cancelled (`scancel`), so that nothing runs for nothing.
pub fn submit(submission: &Submission) -> Result<SubmittedJobs, SlurmError> {
    let folder = submission.folder();
    std::fs::create_dir_all(&folder).map_err(|e| {
        SlurmError(format!(
            "{}: cannot create the job folder: {e}",
            folder.display()
        ))
    })?;
    let array_script = folder.join("task.sh");
    write_script(&array_script, &submission.array_script())?;
    let common = |name: String, log: &Path| {
        vec![
            "--parsable".to_string(),
            format!("--job-name={name}"),
            format!("--output={}", log.display()),
            format!("--chdir={}", submission.workdir.display()),
        ]
    };
    let mut array_args = common(submission.job_name(), &submission.task_log("%a"));
    array_args.push(format!("--array=0-{}", submission.split.task_count() - 1));
    array_args.extend(submission.sbatch_args.iter().cloned());
    let array = sbatch(&array_args, &array_script)?;
    let Split::Parts(_) = submission.split else {
        return Ok(SubmittedJobs { array, merge: None });
    };
    let merge_script = folder.join("merge.sh");
    let mut merge_args = common(
        format!("{}-merge", submission.job_name()),
        &submission.merge_log(),
    );
    merge_args.push(format!("--dependency=afterok:{array}"));
    merge_args.push("--kill-on-invalid-dep=yes".into());
    merge_args.extend(submission.sbatch_args.iter().cloned());
    let merge = write_script(&merge_script, &submission.merge_script())
        .and_then(|()| sbatch(&merge_args, &merge_script));
    match merge {
        Ok(merge) => Ok(SubmittedJobs {
            array,
            merge: Some(merge),
        }),
        Err(e) => {
            let _ = Command::new("scancel").arg(&array).status();
            Err(SlurmError(format!(
                "{e} (the job array {array} was cancelled)"
            )))
        }
    }
}

/// Writes an executable script.
fn write_script(path: &Path, text: &str) -> Result<(), SlurmError> {
    let fail = |e: std::io::Error| SlurmError(format!("{}: cannot write: {e}", path.display()));
    std::fs::write(path, text).map_err(fail)?;
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).map_err(fail)
}

/// Runs `sbatch ARGS SCRIPT`; returns the job id it prints (`--parsable`: `ID[;CLUSTER]`).
fn sbatch(args: &[String], script: &Path) -> Result<String, SlurmError> {
    let output = Command::new("sbatch")
        .args(args)
        .arg(script)
        .output()
        .map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => SlurmError(
                "sbatch not found: is Slurm installed and its commands on PATH? \
                 (docs/farm.md shows the job as a plain shell loop too)"
                    .into(),
            ),
            _ => SlurmError(format!("cannot run sbatch: {e}")),
        })?;
    let stdout = String::from_utf8_lossy(&output.stdout);
    let id = stdout.trim().split(';').next().unwrap_or("").to_string();
    if !output.status.success() || id.is_empty() || !id.chars().all(|c| c.is_ascii_digit()) {
        let stderr = String::from_utf8_lossy(&output.stderr);
        return Err(SlurmError(format!(
            "sbatch refused {} ({}): {}",
            script.display(),
            output.status,
            stderr.trim().lines().collect::<Vec<_>>().join("; ")
        )));
    }
    Ok(id)
}

/// One job (or array task) as `scontrol show job` reports it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JobRecord {
    /// `12` or, for an array task, `12_3` (`12_[0-3]` for tasks still pending together).
    pub id: String,
    /// `PENDING`, `RUNNING`, `COMPLETED`, `FAILED`, ...
    pub state: String,
    /// `EXIT:SIGNAL`.
    pub exit_code: String,
    /// The task's array index (`0-3` for pending tasks listed together), if an array task.
    pub array_task: Option<String>,
}

impl JobRecord {
    /// Whether the job has ended, well or not.
    pub fn ended(&self) -> bool {
        !matches!(
            self.state.as_str(),
            "PENDING"
                | "RUNNING"
                | "CONFIGURING"
                | "COMPLETING"
                | "REQUEUED"
                | "REQUEUE_FED"
                | "REQUEUE_HOLD"
                | "RESIZING"
                | "SUSPENDED"
                | "STOPPED"
                | "SIGNALING"
                | "STAGE_OUT"
                | "RESV_DEL_HOLD"
                | "SPECIAL_EXIT"
        )
    }
}

/// Parses `scontrol show job --oneliner` output: one record per line, `Key=Value` words.
pub fn parse_job_records(text: &str) -> Vec<JobRecord> {
    text.lines()
        .filter(|line| line.contains("JobId="))
        .map(|line| {
            let field = |key: &str| {
                line.split_whitespace()
                    .find_map(|word| word.strip_prefix(key)?.strip_prefix('='))
                    .map(str::to_string)
            };
            let job = field("JobId").unwrap_or_default();
            let array_task = field("ArrayTaskId");
            let id = match (&array_task, field("ArrayJobId")) {
                (Some(task), Some(array)) if task.contains(['-', ',']) => {
                    format!("{array}_[{task}]")
                }
                (Some(task), Some(array)) => format!("{array}_{task}"),
                _ => job,
            };
            JobRecord {
                id,
                state: field("JobState").unwrap_or_default(),
                exit_code: field("ExitCode").unwrap_or_default(),
                array_task,
            }
        })
        .collect()
}

/// The records of job `id` (all tasks of an array).
fn job_records(id: &str) -> Result<Vec<JobRecord>, SlurmError> {
    let output = Command::new("scontrol")
        .args(["show", "job", "--oneliner", id])
        .output()
        .map_err(|e| SlurmError(format!("cannot run scontrol: {e}")))?;
    let records = parse_job_records(&String::from_utf8_lossy(&output.stdout));
    if !output.status.success() || records.is_empty() {
        return Err(SlurmError(format!(
            "scontrol does not know job {id} (any more): {}",
            String::from_utf8_lossy(&output.stderr).trim()
        )));
    }
    Ok(records)
}

/// Polls job `id` until every record of it has ended.
fn wait_for(id: &str) -> Result<Vec<JobRecord>, SlurmError> {
    loop {
        let records = job_records(id)?;
        if records.iter().all(JobRecord::ended) {
            return Ok(records);
        }
        std::thread::sleep(Duration::from_secs(1));
    }
}

/// Blocks until the submitted jobs end: Ok when every array task and the merge job
/// completed; otherwise an error naming the first job that did not, its state and its log.
pub fn wait(submission: &Submission, jobs: &SubmittedJobs) -> Result<(), SlurmError> {
    let tasks = wait_for(&jobs.array)?;
    if let Some(failed) = tasks.iter().find(|t| t.state != "COMPLETED") {
        let log = submission.task_log(failed.array_task.as_deref().unwrap_or("0"));
        return Err(SlurmError(format!(
            "job {} ended {} (exit code {}); see {}{}",
            failed.id,
            failed.state,
            failed.exit_code,
            log.display(),
            match &jobs.merge {
                Some(merge) => {
                    // Slurm would cancel it too (--kill-on-invalid-dep), at its next look.
                    let _ = Command::new("scancel").arg(merge).output();
                    format!("; merge job {merge} cancelled")
                }
                None => String::new(),
            }
        )));
    }
    if let Some(merge) = &jobs.merge {
        let records = wait_for(merge)?;
        if let Some(failed) = records.iter().find(|r| r.state != "COMPLETED") {
            return Err(SlurmError(format!(
                "merge job {} ended {} (exit code {}); see {}",
                failed.id,
                failed.state,
                failed.exit_code,
                submission.merge_log().display()
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_ranges_parse_and_cut_into_tasks() {
        assert_eq!(parse_frame_range("0-24"), Ok((0, 24, 1)));
        assert_eq!(parse_frame_range("1-10:3"), Ok((1, 10, 3)));
        for bad in ["5-4", "1-2:0", "1", "a-b", "-1-3", "1-3:"] {
            assert!(parse_frame_range(bad).is_err(), "{bad}");
        }
        let frames = |first, last, step, per_task| Split::Frames {
            first,
            last,
            step,
            per_task,
        };
        // 1, 4, 7, 10: four frames, two tasks of two.
        assert_eq!(frames(1, 10, 3, 2).task_count(), 2);
        assert_eq!(frames(0, 24, 1, 1).task_count(), 25);
        assert_eq!(frames(0, 24, 1, 10).task_count(), 3);
        assert_eq!(Split::Parts(4).task_count(), 4);
    }

    #[test]
    fn scripts_quote_paths_and_name_the_parts() {
        let submission = Submission {
            program: "/opt/wave trace/wavetrace".into(),
            scene: "/scenes/it's.toml".into(),
            render_flags: vec!["--spp".into(), "8".into()],
            output: "/out/farm.exr".into(),
            split: Split::Parts(3),
            sbatch_args: vec![],
            workdir: "/".into(),
        };
        let task = submission.array_script();
        assert!(task.contains("exec '/opt/wave trace/wavetrace' render '/scenes/it'\\''s.toml' '--spp' '8' --part \"${SLURM_ARRAY_TASK_ID"), "{task}");
        assert!(
            task.contains("-o '/out/farm.exr.slurm/part-'\"${SLURM_ARRAY_TASK_ID"),
            "{task}"
        );
        let merge = submission.merge_script();
        assert!(
            merge.contains("'/out/farm.exr.slurm/part-2.wtpart' -o '/out/farm.exr'"),
            "{merge}"
        );
    }

    #[test]
    fn job_records_are_read_from_scontrol_lines() {
        let text = "JobId=13 ArrayJobId=12 ArrayTaskId=1 JobName=w JobState=FAILED Reason=NonZeroExitCode ExitCode=1:0\n\
                    JobId=12 ArrayJobId=12 ArrayTaskId=2-3 JobName=w JobState=PENDING Reason=None ExitCode=0:0\n\
                    JobId=20 JobName=m JobState=COMPLETED Reason=None ExitCode=0:0\n";
        let records = parse_job_records(text);
        assert_eq!(records.len(), 3);
        assert_eq!(records[0].id, "12_1");
        assert_eq!(records[0].state, "FAILED");
        assert!(records[0].ended());
        assert_eq!(records[1].id, "12_[2-3]");
        assert!(!records[1].ended());
        assert_eq!(records[2].id, "20");
        assert_eq!(records[2].exit_code, "0:0");
    }
}
