//! A Monte Carlo study spread over processes or machines: `probecal study
//! --shard K/N` runs every N-th seed from the K-th (1-based) and writes
//! `shard_K_of_N.yaml` (each seed's outcome, the manifest's SHA-256, the seed
//! range); `probecal study merge` checks that the shards are the N slices of one
//! study and writes the `study.json` and pages one unsharded run writes, byte for
//! byte (the outcomes are YAML, whose numbers read back to the same bits).

use std::path::{Path, PathBuf};
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::core::limits::MAX_SEEDS;
use crate::pipeline::study::{BoundModel, SeedResult};

/// Slice `index` (1-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl FromStr for Shard {
    type Err = ShardError;

    fn from_str(text: &str) -> Result<Shard, ShardError> {
        let fail = || ShardError::NotASlice(text.to_string());
        let (k, n) = text.split_once('/').ok_or_else(fail)?;
        let (index, count) = (
            k.trim().parse::<u64>().map_err(|_| fail())?,
            n.trim().parse::<u64>().map_err(|_| fail())?,
        );
        if index == 0 || index > count || count > MAX_SEEDS {
            return Err(fail());
        }
        Ok(Shard { index, count })
    }
}

impl Shard {
    /// The seeds of this slice: every `count`-th from the `index`-th, so that
    /// slices take about as long (a seed's time does not drift with its number).
    pub fn seeds_of(&self, seeds: &[u64]) -> Vec<u64> {
        seeds
            .iter()
            .enumerate()
            .filter(|(i, _)| *i as u64 % self.count == self.index - 1)
            .map(|(_, s)| *s)
            .collect()
    }

    /// `shard_K_of_N.yaml`.
    pub fn file_name(&self) -> String {
        format!("shard_{}_of_{}.yaml", self.index, self.count)
    }
}

/// What one slice writes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardFile {
    pub experiment: String,
    /// SHA-256 of the manifest file the slice ran.
    pub manifest_sha256: String,
    /// The whole study's seeds: `first_seed` and how many.
    pub first_seed: u64,
    pub seeds: u64,
    pub shard: Shard,
    /// The model of the seeds' bound (left out for point pairs).
    #[serde(default, skip_serializing_if = "BoundModel::is_point_pairs")]
    pub bound: BoundModel,
    pub results: Vec<SeedResult>,
}

/// Writes `<out>/shard_K_of_N.yaml` (through a temporary name).
pub fn write(out: &Path, file: &ShardFile) -> Result<PathBuf, ShardError> {
    let path = out.join(file.shard.file_name());
    let file_error = |e: &dyn std::fmt::Display| ShardError::File {
        path: path.clone(),
        message: e.to_string(),
    };
    let text = serde_yaml::to_string(file).map_err(|e| file_error(&e))?;
    crate::io::fs::write_atomic(&path, text.as_bytes()).map_err(|e| file_error(&e.message))?;
    Ok(path)
}

/// Reads one shard file; an error names the file (and the line and field).
pub fn read(path: &Path) -> Result<ShardFile, ShardError> {
    let file_error = |e: &dyn std::fmt::Display| ShardError::File {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let text = crate::io::yaml_limits::read(path, "a shard file").map_err(|e| file_error(&e))?;
    let file: ShardFile = serde_yaml::from_str(&text).map_err(|e| file_error(&e))?;
    implausible(&file).map_or(Ok(file), |why| Err(file_error(&why)))
}

/// Largest error a seed may report, mm: far beyond any calibration that ran.
const MAX_SEED_ERROR_MM: f64 = 1000.0;

/// Why a shard's numbers cannot be a study's outcomes, if they cannot: an
/// error or a bound that is negative, not finite or absurd, a method listed
/// twice for one seed.
fn implausible(file: &ShardFile) -> Option<String> {
    let plausible = |v: f64| v.is_finite() && (0.0..=MAX_SEED_ERROR_MM).contains(&v);
    for r in &file.results {
        for (i, (method, rms)) in r.rms_error_mm.iter().enumerate() {
            if !plausible(*rms) {
                return Some(format!(
                    "seed {}: method `{method}`'s RMS error {rms} mm is not an error (0 to {MAX_SEED_ERROR_MM} mm)",
                    r.seed
                ));
            }
            if r.rms_error_mm[..i].iter().any(|(m, _)| m == method) {
                return Some(format!("seed {}: method `{method}` is listed twice", r.seed));
            }
        }
        if let Some(bound) = r.crlb_rms_mm.filter(|b| !plausible(*b)) {
            return Some(format!(
                "seed {}: the bound {bound} mm is not an error (0 to {MAX_SEED_ERROR_MM} mm)",
                r.seed
            ));
        }
    }
    None
}

/// Why shards cannot be read, written or joined into one study.
#[derive(Debug, thiserror::Error)]
pub enum ShardError {
    #[error("`{0}` is not K/N with 1 ≤ K ≤ N ≤ {MAX_SEEDS} (e.g. 2/5)")]
    NotASlice(String),
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    #[error("no shard files given")]
    NoShards,
    #[error("{}: {what} differs from {}'s; the shards are not of one study", path.display(), first.display())]
    Differs {
        path: PathBuf,
        first: PathBuf,
        what: &'static str,
    },
    #[error("{} and {} are both shard {index}/{count}", first.display(), second.display())]
    Twice {
        first: PathBuf,
        second: PathBuf,
        index: u64,
        count: u64,
    },
    #[error("{}: holds seeds {got:?}, shard {index}/{count} of {seeds} seeds from {first_seed} is {want:?}", path.display())]
    WrongSeeds {
        path: PathBuf,
        got: Vec<u64>,
        index: u64,
        count: u64,
        seeds: u64,
        first_seed: u64,
        want: Vec<u64>,
    },
    #[error("shards {} are missing", .0.join(", "))]
    Missing(Vec<String>),
}

/// The outcomes of every seed, in seed order, from shards that are exactly the
/// N slices of one study; otherwise what is wrong, naming the file.
pub fn join(shards: &[(PathBuf, ShardFile)]) -> Result<(String, BoundModel, Vec<SeedResult>), ShardError> {
    let Some((first_path, first)) = shards.first() else {
        return Err(ShardError::NoShards);
    };
    let count = first.shard.count;
    let mut seen: Vec<Option<&Path>> = vec![None; count as usize];
    for (path, s) in shards {
        let differs = |what: &'static str| ShardError::Differs {
            path: path.clone(),
            first: first_path.clone(),
            what,
        };
        if s.manifest_sha256 != first.manifest_sha256 {
            return Err(differs("the manifest (SHA-256)"));
        }
        if s.experiment != first.experiment {
            return Err(differs("the experiment"));
        }
        if s.bound != first.bound {
            return Err(differs("the bound's model"));
        }
        if (s.first_seed, s.seeds) != (first.first_seed, first.seeds) {
            return Err(differs("the seed range"));
        }
        if s.shard.count != count {
            return Err(differs("the number of shards"));
        }
        let slot = &mut seen[(s.shard.index - 1) as usize];
        if let Some(other) = slot {
            return Err(ShardError::Twice {
                first: other.to_path_buf(),
                second: path.clone(),
                index: s.shard.index,
                count,
            });
        }
        *slot = Some(path);
        let all: Vec<u64> = (s.first_seed..s.first_seed.saturating_add(s.seeds)).collect();
        let want = s.shard.seeds_of(&all);
        let got: Vec<u64> = s.results.iter().map(|r| r.seed).collect();
        if got != want {
            return Err(ShardError::WrongSeeds {
                path: path.clone(),
                got,
                index: s.shard.index,
                count,
                seeds: s.seeds,
                first_seed: s.first_seed,
                want,
            });
        }
    }
    let missing: Vec<String> = (1..=count)
        .filter(|k| seen[(*k - 1) as usize].is_none())
        .map(|k| format!("{k}/{count}"))
        .collect();
    if !missing.is_empty() {
        return Err(ShardError::Missing(missing));
    }
    let mut results: Vec<SeedResult> = shards.iter().flat_map(|(_, s)| s.results.iter().cloned()).collect();
    results.sort_by_key(|r| r.seed);
    Ok((first.experiment.clone(), first.bound, results))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(seed: u64) -> SeedResult {
        SeedResult {
            seed,
            // Numbers whose shortest decimal has 17 digits read back to the same bits.
            rms_error_mm: vec![
                ("reported".into(), 0.1 + seed as f64 / 3.0),
                ("lmeds".into(), 1.0 / 7.0),
            ],
            crlb_rms_mm: Some(2.0f64.sqrt() / 10.0),
            frames_used: 40,
        }
    }

    /// A negative, absurd or not-a-number error, or a method listed twice, is
    /// refused when the shard is read, naming the file: merged, it would be a
    /// study's mean.
    #[test]
    fn implausible_outcomes_are_refused_on_reading() {
        let dir = std::env::temp_dir().join(format!("probecal-shard-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (_, good) = shard(1, 1, 2);
        let path = write(&dir, &good).unwrap();
        assert_eq!(read(&path).unwrap(), good);
        for (edit, expect) in [
            ((0usize, -0.3), "method `reported`'s RMS error -0.3 mm is not an error"),
            ((1usize, f64::NAN), "method `lmeds`'s RMS error NaN mm is not an error"),
            ((0usize, 5e3), "RMS error 5000 mm is not an error"),
        ] {
            let mut bad = good.clone();
            bad.results[1].rms_error_mm[edit.0].1 = edit.1;
            let path = write(&dir, &bad).unwrap();
            let e = read(&path).unwrap_err().to_string();
            assert!(e.contains(&path.display().to_string()) && e.contains(expect), "{e}");
        }
        let mut twice = good.clone();
        twice.results[0].rms_error_mm[1].0 = "reported".into();
        let path = write(&dir, &twice).unwrap();
        assert!(read(&path)
            .unwrap_err()
            .to_string()
            .contains("method `reported` is listed twice"));
        std::fs::remove_dir_all(&dir).ok();
    }

    fn shard(index: u64, count: u64, seeds: u64) -> (PathBuf, ShardFile) {
        let shard = Shard { index, count };
        let all: Vec<u64> = (1000..1000 + seeds).collect();
        (
            PathBuf::from(shard.file_name()),
            ShardFile {
                experiment: "rig".into(),
                manifest_sha256: "ab".into(),
                first_seed: 1000,
                seeds,
                shard,
                bound: BoundModel::PointPairs,
                results: shard.seeds_of(&all).into_iter().map(outcome).collect(),
            },
        )
    }

    #[test]
    fn k_of_n_is_parsed_and_bounded() {
        assert_eq!("2/5".parse::<Shard>().ok(), Some(Shard { index: 2, count: 5 }));
        for bad in ["0/5", "6/5", "5", "a/b", "1/0", "1/10001"] {
            let e = bad.parse::<Shard>().unwrap_err();
            assert!(e.to_string().contains("is not K/N"), "{bad}: {e}");
        }
    }

    #[test]
    fn the_slices_cover_every_seed_once() {
        let seeds: Vec<u64> = (1000..1013).collect();
        let mut all: Vec<u64> = (1..=5)
            .flat_map(|k| Shard { index: k, count: 5 }.seeds_of(&seeds))
            .collect();
        all.sort();
        assert_eq!(all, seeds);
    }

    #[test]
    fn joined_shards_are_the_seeds_in_order_and_numbers_survive_the_file() {
        let shards: Vec<(PathBuf, ShardFile)> = (1..=3)
            .map(|k| shard(k, 3, 7))
            .map(|(p, s)| {
                let text = serde_yaml::to_string(&s).unwrap();
                (p, serde_yaml::from_str(&text).unwrap())
            })
            .collect();
        let (experiment, bound, results) = join(&shards).unwrap();
        assert_eq!(experiment, "rig");
        assert_eq!(bound, BoundModel::PointPairs);
        assert_eq!(results, (1000..1007).map(outcome).collect::<Vec<_>>());
    }

    #[test]
    fn shards_that_are_not_one_study_are_refused() {
        let mut missing = vec![shard(1, 3, 7), shard(3, 3, 7)];
        assert_eq!(join(&missing).unwrap_err().to_string(), "shards 2/3 are missing");
        missing.push(shard(3, 3, 7));
        assert!(join(&missing).unwrap_err().to_string().contains("are both shard 3/3"));
        let mut other = vec![shard(1, 2, 7), shard(2, 2, 7)];
        other[1].1.manifest_sha256 = "cd".into();
        assert!(join(&other)
            .unwrap_err()
            .to_string()
            .contains("the manifest (SHA-256) differs"));
        let mut cut = vec![shard(1, 2, 7), shard(2, 2, 7)];
        cut[1].1.results.pop();
        assert!(join(&cut).unwrap_err().to_string().contains("holds seeds [1001, 1003]"));
        let mut range = vec![shard(1, 2, 7), shard(2, 2, 8)];
        range[1].1.results = shard(2, 2, 7).1.results;
        assert!(join(&range).unwrap_err().to_string().contains("the seed range differs"));
        let mut model = vec![shard(1, 2, 7), shard(2, 2, 7)];
        model[1].1.bound = BoundModel::SphereFit;
        assert!(join(&model)
            .unwrap_err()
            .to_string()
            .contains("the bound's model differs"));
    }
}
