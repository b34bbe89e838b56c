//! How much memory the process may still take, and the refusal of a scene that would not fit:
//! running out of memory is bad input (a scene too large for the machine), reported before the
//! large structures are built rather than ending in an allocation abort.
//!
//! The limit is the smallest of what Linux reports: `MemAvailable` (/proc/meminfo), the
//! address-space limit (`ulimit -v`, /proc/self/limits) less what the process already maps,
//! and a cgroup v2 memory limit less its current use; resident memory and address space are
//! compared with separate estimates. Elsewhere nothing is known and nothing is refused.
//! [`trace_phase`] is the diagnostic that finds where the peaks are.

use std::path::Path;

/// What the process can still take, as far as the system says.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Available {
    /// Resident bytes: `MemAvailable`, or the cgroup's limit less its use, whichever is less.
    pub resident: Option<u64>,
    /// Address space: the `ulimit -v` limit less what the process already maps (which
    /// counts reserved memory such as thread stacks and allocator arenas).
    pub address_space: Option<u64>,
}

/// What the process can still take now.
pub fn available() -> Available {
    let read = |path: &str| std::fs::read_to_string(path).ok();
    let meminfo = read("/proc/meminfo");
    let cgroup_free = read("/sys/fs/cgroup/memory.max")
        .and_then(|m| m.trim().parse::<u64>().ok())
        .map(|max| {
            let used = read("/sys/fs/cgroup/memory.current").and_then(|c| c.trim().parse().ok());
            max.saturating_sub(used.unwrap_or(0))
        });
    let resident = [
        meminfo
            .as_deref()
            .and_then(|m| kib_field(m, "MemAvailable:")),
        cgroup_free,
    ]
    .into_iter()
    .flatten()
    .min();
    let address_space = read("/proc/self/limits")
        .as_deref()
        .and_then(address_space_limit)
        .map(|limit| {
            let status = read("/proc/self/status");
            let mapped = status.as_deref().and_then(|s| kib_field(s, "VmSize:"));
            limit.saturating_sub(mapped.unwrap_or(0))
        });
    Available {
        resident,
        address_space,
    }
}

/// A `Name:   1234 kB` field of a /proc file, in bytes.
fn kib_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kib: u64 = line[name.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kib * 1024)
}

/// The soft "Max address space" of /proc/self/limits in bytes; `None` when unlimited.
fn address_space_limit(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    let soft = line["Max address space".len()..]
        .split_whitespace()
        .next()?;
    soft.parse().ok()
}

/// `bytes` in GiB for messages.
fn gib(bytes: u64) -> f64 {
    bytes as f64 / (1u64 << 30) as f64
}

/// What building something takes: resident bytes and address space (more: allocator arenas
/// and growing vectors reserve before they touch).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Needed {
    pub resident: u64,
    pub address_space: u64,
}

/// Refuses to build something (`what` says what) when the process cannot have what it needs:
/// the error names the file, the estimate and what is available.
pub(crate) fn check_fits(
    path: &Path,
    what: &str,
    needed: Needed,
    available: Available,
) -> crate::Result<()> {
    match shortfall(what, needed, available) {
        Some(why) => Err(crate::Error::input(
            path,
            None,
            format!("{why}; use a smaller model or fewer copies of it"),
        )),
        None => Ok(()),
    }
}

/// Why something (`what` says what) cannot have the memory it needs, naming the estimate
/// and the limit it exceeds; `None` when it fits (or nothing is known).
pub(crate) fn shortfall(what: &str, needed: Needed, available: Available) -> Option<String> {
    let (need, have, limit) = [
        (needed.resident, available.resident, "free memory"),
        (
            needed.address_space,
            available.address_space,
            "the address-space limit (ulimit -v)",
        ),
    ]
    .into_iter()
    .find_map(|(need, have, limit)| {
        have.filter(|&have| need > have)
            .map(|have| (need, have, limit))
    })?;
    Some(format!(
        "the scene does not fit in memory: {what} needs about {:.1} GiB, and {limit} leaves \
         {:.1} GiB",
        gib(need),
        gib(have)
    ))
}

/// A diagnostic for finding where memory peaks: with the environment variable
/// `WAVETRACE_MEMTRACE` set, prints the resident memory now and its peak since the previous
/// call (or the start), then resets that peak (Linux: `/proc/self/clear_refs`; so a later
/// `/usr/bin/time -v` maximum covers only the last phase). `phase` names what just ended.
pub fn trace_phase(phase: &str) {
    if std::env::var_os("WAVETRACE_MEMTRACE").is_none() {
        return;
    }
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let mib = |field| kib_field(&status, field).unwrap_or(0) >> 20;
    eprintln!(
        "memory after {phase:>12}: {:5} MiB resident, peak since the last phase {:5} MiB",
        mib("VmRSS:"),
        mib("VmHWM:")
    );
    // Writing 5 resets the peak (VmHWM) to the current resident size.
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_fields_parse() {
        let meminfo = "MemTotal:       24570000 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(kib_field(meminfo, "MemAvailable:"), Some(20_000_000 * 1024));
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max address space         6442450944           unlimited            bytes     \n";
        assert_eq!(address_space_limit(limits), Some(6_442_450_944));
        let unlimited =
            "Max address space         unlimited            unlimited            bytes     \n";
        assert_eq!(address_space_limit(unlimited), None);
    }

    #[test]
    fn a_scene_larger_than_what_is_available_is_refused_with_both_figures() {
        let path = Path::new("forest.gltf");
        let needed = |gib: u64| Needed {
            resident: gib << 30,
            address_space: (gib << 30) * 2,
        };
        let have = |resident: Option<u64>, address_space: Option<u64>| Available {
            resident: resident.map(|g| g << 30),
            address_space: address_space.map(|g| g << 30),
        };
        let e = check_fits(path, "100 triangles", needed(30), have(Some(20), None)).unwrap_err();
        let text = e.to_string();
        assert!(text.starts_with("forest.gltf"), "{text}");
        assert!(
            text.contains("30.0 GiB") && text.contains("20.0 GiB"),
            "{text}"
        );
        assert!(text.contains("free memory"), "{text}");
        let e = check_fits(path, "x", needed(4), have(Some(20), Some(6))).unwrap_err();
        assert!(e.to_string().contains("ulimit -v"), "{e}");
        assert!(check_fits(path, "x", needed(2), have(Some(20), Some(6))).is_ok());
        assert!(check_fits(path, "x", needed(1 << 20), Available::default()).is_ok());
        // Linux always reports the free memory.
        if cfg!(target_os = "linux") {
            assert!(available().resident.is_some_and(|b| b > 0));
        }
    }
}
