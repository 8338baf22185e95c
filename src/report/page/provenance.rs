//! `provenance.json`: what produced a run folder — probecal's version and commit,
//! OpenCV's version, the manifest's and every input file's SHA-256, seeds, thread
//! count, start time. It is kept apart from the fingerprinted outputs (tables,
//! summary, pages), which do not carry times or machine facts.

use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::Serialize;
use sha2::{Digest, Sha256};

use crate::io::fs::{file_sha256, hex};

#[derive(Debug, Serialize)]
pub struct InputFile {
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
}

#[derive(Debug, Serialize)]
pub struct Provenance {
    pub probecal_version: &'static str,
    pub git_commit: &'static str,
    pub opencv_version: String,
    pub command: Vec<String>,
    pub manifest: String,
    pub manifest_sha256: String,
    pub dataset: String,
    pub dataset_folder: String,
    pub seed: Option<u64>,
    pub threads: usize,
    pub started_utc: String,
    pub elapsed_s: f64,
    /// Seconds per stage of this dataset's run (camera runs; absent where the
    /// run times no stages).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub timings_s: Vec<(String, f64)>,
    /// Peak resident memory of the process so far (Linux VmHWM), MB.
    pub peak_memory_mb: Option<f64>,
    /// SHA-256 over the input files' own hashes, in path order.
    pub inputs_sha256: String,
    pub inputs: Vec<InputFile>,
}

impl Provenance {
    /// The provenance of a run of `manifest` over `inputs`, started at `started`
    /// (no seed, no stage timings: set them where the run has them).
    pub fn new(
        manifest: &Path,
        manifest_sha256: &str,
        dataset: &str,
        dataset_folder: &Path,
        input_files: &[PathBuf],
        started: SystemTime,
    ) -> Provenance {
        let (inputs_sha256, inputs) = hash_inputs(input_files);
        Provenance {
            probecal_version: env!("CARGO_PKG_VERSION"),
            git_commit: GIT_COMMIT,
            opencv_version: opencv_version(),
            command: std::env::args().collect(),
            manifest: manifest.to_string_lossy().to_string(),
            manifest_sha256: manifest_sha256.to_string(),
            dataset: dataset.to_string(),
            dataset_folder: dataset_folder.to_string_lossy().to_string(),
            seed: None,
            threads: crate::core::parallel::threads(),
            started_utc: rfc3339(started),
            elapsed_s: started.elapsed().map(|d| d.as_secs_f64()).unwrap_or(0.0),
            timings_s: Vec::new(),
            peak_memory_mb: peak_memory_mb(),
            inputs_sha256,
            inputs,
        }
    }

    /// Writes `provenance.json` into `folder`.
    pub fn write(&self, folder: &Path) -> Result<(), crate::report::error::OutputError> {
        let text = serde_json::to_string_pretty(self)?;
        crate::io::fs::write_atomic(&folder.join("provenance.json"), text.as_bytes()).map_err(Into::into)
    }
}

/// Hashes input files (missing ones are listed with an empty hash).
pub fn hash_inputs(paths: &[PathBuf]) -> (String, Vec<InputFile>) {
    let mut sorted: Vec<&PathBuf> = paths.iter().collect();
    sorted.sort();
    sorted.dedup();
    let inputs: Vec<InputFile> = crate::core::parallel::parallel_map(sorted.len(), |i| {
        let p = sorted[i];
        let (bytes, sha256) = file_sha256(p).unwrap_or((0, String::new()));
        InputFile {
            path: p.to_string_lossy().replace('\\', "/"),
            bytes,
            sha256,
        }
    });
    let mut all = Sha256::new();
    for i in &inputs {
        all.update(i.sha256.as_bytes());
    }
    (hex(&all.finalize()), inputs)
}

/// UTC time as RFC 3339 (seconds), without a date-time crate.
pub fn rfc3339(time: SystemTime) -> String {
    let secs = time.duration_since(UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Civil date from days since 1970-01-01 (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

pub fn opencv_version() -> String {
    opencv::core::get_version_string().unwrap_or_else(|_| "unknown".into())
}

pub const GIT_COMMIT: &str = env!("PROBECAL_GIT_COMMIT");

/// Peak resident memory of this process (VmHWM of /proc/self/status), MB.
pub fn peak_memory_mb() -> Option<f64> {
    let status = crate::io::fs::read_text_capped(std::path::Path::new("/proc/self/status"), 1 << 20).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    #[test]
    fn formats_utc_dates() {
        assert_eq!(rfc3339(UNIX_EPOCH), "1970-01-01T00:00:00Z");
        assert_eq!(
            rfc3339(UNIX_EPOCH + Duration::from_secs(951_782_400)),
            "2000-02-29T00:00:00Z"
        );
        assert_eq!(
            rfc3339(UNIX_EPOCH + Duration::from_secs(1_795_324_530)),
            "2026-11-22T05:15:30Z"
        );
    }
}
