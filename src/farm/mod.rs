//! Render farms: one frame rendered in parts on many machines and merged bit for bit
//! ([`parts`]), and the jobs that do it on a Slurm cluster ([`slurm`]). `docs/farm.md` says
//! how to use them and why a merged frame equals the frame rendered whole.

pub mod parts;
pub mod slurm;

pub use parts::{MergedFrame, PartIndex, merge_parts, part_rows, write_part};

/// FNV-1a, 64 bits: the fingerprint of a scene file's bytes and of a part file's contents (a
/// check against mix-ups and truncation, not against forgery). Stable across platforms and
/// Rust versions, unlike `std`'s hasher.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |hash, &byte| {
        (hash ^ byte as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}
