//! Images paired with the tracker's transforms at their timestamps, as a PLUS
//! buffer does: a transform sample at the image's time is taken as it is;
//! otherwise the pose is interpolated between the samples on either side
//! (translation linearly, rotation by spherical interpolation), when they are
//! no further apart than the gap limit. An image waits until every transform has
//! a sample at or after its time, or the stream has ended.
//!
//! A paired frame's fields are a PLUS sequence frame's: `Timestamp`,
//! `<Name>Transform` and `<Name>TransformStatus` (`INVALID` when no pose could
//! be given, with `<Name>TransformReason` saying why).

use std::collections::{BTreeMap, VecDeque};
use std::time::Instant;

use nalgebra::{Matrix3, Matrix4};

/// Samples nearer than this are at the same time, s (timestamps travel at 2^-32 s).
const SAME_TIME_S: f64 = 1e-6;
/// Transform samples kept per name (older ones are dropped once no image can
/// need them; this bounds a stream of transforms with no images).
const MAX_SAMPLES: usize = 100_000;

/// An image waiting for its transforms.
#[derive(Debug, Clone)]
pub struct PendingImage {
    pub timestamp_s: f64,
    pub pixels: Vec<u8>,
    /// When its message was complete.
    pub received: Instant,
}

/// An image with its frame fields.
#[derive(Debug, Clone)]
pub struct PairedImage {
    pub image: PendingImage,
    pub fields: BTreeMap<String, String>,
    /// Transforms that could not be given, with why.
    pub missing: Vec<String>,
}

pub struct Pairing {
    names: Vec<String>,
    max_gap_s: f64,
    samples: BTreeMap<String, Vec<(f64, Matrix4<f64>)>>,
    pending: VecDeque<PendingImage>,
}

/// A transform's sample could not be used.
#[derive(Debug, Clone, PartialEq)]
pub struct SampleRefused(pub String);

impl Pairing {
    /// Pairs images with the transforms `names` (e.g. `ProbeToTracker`).
    pub fn new(names: &[String], max_gap_s: f64) -> Pairing {
        Pairing {
            names: names.to_vec(),
            max_gap_s,
            samples: names.iter().map(|n| (n.clone(), Vec::new())).collect(),
            pending: VecDeque::new(),
        }
    }

    /// Whether `name` is one of the transforms paired.
    pub fn wants(&self, name: &str) -> bool {
        self.samples.contains_key(name)
    }

    /// Images waiting.
    pub fn waiting(&self) -> usize {
        self.pending.len()
    }

    /// A transform sample; refused when its time runs backwards or it is not rigid.
    pub fn add_transform(&mut self, name: &str, time_s: f64, m: Matrix4<f64>) -> Result<(), SampleRefused> {
        let Some(list) = self.samples.get_mut(name) else {
            return Ok(());
        };
        let r = m.fixed_view::<3, 3>(0, 0).into_owned();
        let off = (r.transpose() * r - Matrix3::identity()).abs().max();
        if !(off < 1e-4 && r.determinant() > 0.0) {
            return Err(SampleRefused(format!(
                "not a rotation: |RᵀR − I| reaches {off:.2e} (limit 1e-4) or det R ≤ 0"
            )));
        }
        match list.last() {
            Some(&(last, _)) if time_s < last - SAME_TIME_S => {
                return Err(SampleRefused(format!(
                    "timestamp {time_s:.6} s runs backwards (the previous sample is at {last:.6} s)"
                )))
            }
            Some(&(last, _)) if (time_s - last).abs() <= SAME_TIME_S => {
                list.pop();
            }
            _ => {}
        }
        list.push((time_s, m));
        if list.len() > MAX_SAMPLES {
            list.drain(..list.len() - MAX_SAMPLES);
        }
        Ok(())
    }

    pub fn add_image(&mut self, image: PendingImage) {
        self.pending.push_back(image);
    }

    /// Images whose transforms are all known (every one, once `ended`), in
    /// arrival order.
    pub fn ready(&mut self, ended: bool) -> Vec<PairedImage> {
        let mut out = Vec::new();
        while let Some(front) = self.pending.front() {
            let t = front.timestamp_s;
            let complete = self
                .samples
                .values()
                .all(|list| list.last().is_some_and(|&(last, _)| last >= t - SAME_TIME_S));
            if !(complete || ended) {
                break;
            }
            let Some(image) = self.pending.pop_front() else { break };
            out.push(self.pair(image));
        }
        // Samples before the oldest waiting image (one kept) are not needed again.
        if let Some(oldest) = self
            .pending
            .front()
            .map(|p| p.timestamp_s)
            .or(out.last().map(|p| p.image.timestamp_s))
        {
            for list in self.samples.values_mut() {
                let before = list.partition_point(|&(s, _)| s < oldest - SAME_TIME_S);
                if before > 1 {
                    list.drain(..before - 1);
                }
            }
        }
        out
    }

    fn pair(&self, image: PendingImage) -> PairedImage {
        let t = image.timestamp_s;
        let mut fields = BTreeMap::from([("Timestamp".to_string(), format!("{t:.9}"))]);
        let mut missing = Vec::new();
        for name in &self.names {
            let list = &self.samples[name];
            let (matrix, status) = match pose_at(list, t, self.max_gap_s) {
                Ok(m) => (m, "OK"),
                Err(miss) => {
                    let reason = miss.to_string();
                    fields.insert(format!("{name}TransformReason"), reason.clone());
                    missing.push(format!("{name}: {reason}"));
                    (Matrix4::identity(), "INVALID")
                }
            };
            let numbers: Vec<String> = (0..16).map(|i| format!("{}", matrix[(i / 4, i % 4)])).collect();
            fields.insert(format!("{name}Transform"), numbers.join(" "));
            fields.insert(format!("{name}TransformStatus"), status.to_string());
        }
        PairedImage { image, fields, missing }
    }
}

/// Why an image has no pose of one transform.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum PairMiss {
    #[error("no sample {side} the image's time {t_s:.6} s")]
    Outside { side: &'static str, t_s: f64 },
    #[error("the samples around the image's time are {gap_s:.3} s apart (limit {limit_s} s)")]
    Gap { gap_s: f64, limit_s: f64 },
}

/// The pose at `t` from time-ordered samples.
fn pose_at(list: &[(f64, Matrix4<f64>)], t: f64, max_gap_s: f64) -> Result<Matrix4<f64>, PairMiss> {
    let after = list.partition_point(|&(s, _)| s < t - SAME_TIME_S);
    if let Some(&(s, m)) = list.get(after) {
        if (s - t).abs() <= SAME_TIME_S {
            return Ok(m);
        }
    }
    let (Some(&(t0, a)), Some(&(t1, b))) = (after.checked_sub(1).and_then(|i| list.get(i)), list.get(after)) else {
        let side = if after == 0 { "before" } else { "after" };
        return Err(PairMiss::Outside { side, t_s: t });
    };
    if t1 - t0 > max_gap_s {
        return Err(PairMiss::Gap {
            gap_s: t1 - t0,
            limit_s: max_gap_s,
        });
    }
    Ok(crate::core::trajectory::interpolate_matrix(
        &a,
        &b,
        (t - t0) / (t1 - t0),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Vector3};

    fn image(t: f64) -> PendingImage {
        PendingImage {
            timestamp_s: t,
            pixels: vec![0; 4],
            received: Instant::now(),
        }
    }

    fn shifted(x: f64, angle: f64) -> Matrix4<f64> {
        let mut m = Rotation3::from_axis_angle(&Vector3::z_axis(), angle).to_homogeneous();
        m[(0, 3)] = x;
        m
    }

    #[test]
    fn an_image_waits_for_a_later_sample_then_is_interpolated() {
        let names = vec!["ProbeToTracker".to_string()];
        let mut p = Pairing::new(&names, 0.1);
        p.add_transform("ProbeToTracker", 1.0, shifted(0.0, 0.0)).unwrap();
        p.add_image(image(1.02));
        assert!(p.ready(false).is_empty());
        p.add_transform("ProbeToTracker", 1.04, shifted(4.0, 0.2)).unwrap();
        let done = p.ready(false);
        assert_eq!(done.len(), 1);
        let values: Vec<f64> = done[0].fields["ProbeToTrackerTransform"]
            .split(' ')
            .map(|v| v.parse().unwrap())
            .collect();
        assert!((values[3] - 2.0).abs() < 1e-9, "{values:?}");
        // Halfway in angle too: cos(0.1).
        assert!((values[0] - 0.1f64.cos()).abs() < 1e-9);
        assert_eq!(done[0].fields["ProbeToTrackerTransformStatus"], "OK");
    }

    #[test]
    fn gaps_ends_and_backward_times_are_said() {
        let names = vec!["ProbeToTracker".to_string()];
        let mut p = Pairing::new(&names, 0.1);
        p.add_transform("ProbeToTracker", 1.0, shifted(0.0, 0.0)).unwrap();
        p.add_transform("ProbeToTracker", 1.5, shifted(1.0, 0.0)).unwrap();
        let e = p.add_transform("ProbeToTracker", 1.2, shifted(1.0, 0.0)).unwrap_err();
        assert!(e.0.contains("backwards"), "{e:?}");
        let mut scaled = shifted(0.0, 0.0);
        scaled[(0, 0)] = 2.0;
        assert!(p.add_transform("ProbeToTracker", 1.6, scaled).is_err());
        p.add_image(image(1.2));
        p.add_image(image(1.7));
        let done = p.ready(true);
        assert_eq!(done.len(), 2);
        assert!(done[0].missing[0].contains("0.500 s apart"), "{:?}", done[0].missing);
        assert!(done[1].missing[0].contains("no sample after"), "{:?}", done[1].missing);
        assert_eq!(done[1].fields["ProbeToTrackerTransformStatus"], "INVALID");
    }
}
