//! Live calibration from an OpenIGTLink stream (PlusServer's): IMAGE messages
//! from the image device and TRANSFORM messages from the probe's and the
//! reference's devices, paired at the images' timestamps (see
//! [`crate::pipeline::live::igtl_pairing`]); each paired frame is segmented, posed, predicted
//! and refitted as the file replay does ([`crate::pipeline::live`]). The acquisition ends
//! on a STRING message from the end device, a silence, an interrupt, or the
//! server closing the connection. Then the received frames are written as a
//! PLUS sequence file, the batch pipeline runs on it (so the result is
//! `probecal run`'s on that file), and the calibration is sent back as a
//! TRANSFORM message on the same connection.
//!
//! Every message is accounted for: used, ignored (another device or type), or
//! skipped with its reason (bad CRC, a body that contradicts its sizes, an
//! image that is not 8-bit grey or changes size, a transform that is not a
//! rotation or runs backwards in time).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use nalgebra::Matrix4;

use crate::io::igtl::connection::{Connection, Event};
use crate::io::igtl::message::{self, Body, Header};
use crate::io::igtl::reader::Reader;
use crate::io::igtl::IgtlError;
use crate::io::plus::sequence::{Sequence, MAX_FRAME_PIXELS};
use crate::manifest::tracked::LiveStream;
use crate::pipeline::live::igtl_pairing::{Pairing, PendingImage};
use crate::pipeline::live::volume::{volume_message, LiveVolume, VolumeRequest};
use crate::pipeline::live::{finish, live_offset_s, Arrived, LagQueue, LiveFrame, State};
use crate::pipeline::sequence_frames::{pattern_geometry, segment_frame};
use crate::pipeline::tracked::{self, segmentation_inputs, Role, TrackedError, TrackedInputs, TrackedRun};

/// Skip reasons listed one by one (the rest are counted).
const MAX_LISTED: usize = 50;
/// Pixels held for the received frames: past it the acquisition ends (a
/// 820x616 stream holds 4250 frames, 5.5 minutes at 12.8 frames/s).
pub const MAX_RECEIVED_PIXELS: usize = 1 << 31;

/// Where to connect and what to listen for.
#[derive(Debug, Clone)]
pub struct StreamSettings {
    /// `HOST:PORT` of the OpenIGTLink server.
    pub address: String,
    pub stream: LiveStream,
    /// A volume reconstructed while the frames arrive, sent back every N frames.
    pub volume: Option<VolumeRequest>,
}

/// Why a session could not start.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// No connection to the server.
    #[error(transparent)]
    Stream(#[from] IgtlError),
    /// The tracker's lag to apply while frames arrive could not be had.
    #[error(transparent)]
    Lag(#[from] TrackedError),
    /// The live volume's settings.
    #[error(transparent)]
    Volume(#[from] crate::pipeline::live::volume::VolumeSetupError),
}

/// Why the acquisition ended.
#[derive(Debug, Clone, PartialEq)]
pub enum Ending {
    /// A STRING message from the end device.
    EndMessage,
    Silence,
    Interrupted,
    /// The server closed the connection between messages.
    Closed,
    /// The server closed the connection inside a message.
    Cut(String),
    /// The stream could not be read on (a header that cannot be framed, a body
    /// above the limit, a socket error): the frames before it are kept.
    Broken(IgtlError),
    /// The received frames reached [`MAX_RECEIVED_PIXELS`].
    FrameLimit,
}

impl Ending {
    pub fn describe(&self, stream: &LiveStream) -> String {
        match self {
            Ending::EndMessage => format!("a STRING message from `{}`", stream.end_device),
            Ending::Silence => format!("{} s without a message", stream.silence_s),
            Ending::Interrupted => "an interrupt (Ctrl-C)".into(),
            Ending::Closed => "the server closing the connection".into(),
            Ending::Cut(reason) => format!("a cut stream: {reason}"),
            Ending::Broken(reason) => format!("a stream that could not be read on: {reason}"),
            Ending::FrameLimit => format!("the received frames reaching {MAX_RECEIVED_PIXELS} pixels"),
        }
    }

    fn connected(&self) -> bool {
        !matches!(self, Ending::Closed | Ending::Cut(_) | Ending::Broken(_))
    }

    /// An ending the session did not choose (the stream failed under it).
    pub fn abnormal(&self) -> bool {
        matches!(self, Ending::Cut(_) | Ending::Broken(_))
    }
}

/// What arrived, by fate.
#[derive(Debug, Clone, Default)]
pub struct StreamCounts {
    /// Messages read, by `TYPE device`.
    pub messages: BTreeMap<String, usize>,
    /// Messages of other devices or types, by `TYPE device`.
    pub ignored: BTreeMap<String, usize>,
    pub skipped: usize,
    /// The first skips' `TYPE from device: reason`.
    pub skip_reasons: Vec<String>,
    pub images_received: usize,
    /// Images paired with transforms (each is a frame of the received sequence).
    pub frames: usize,
    /// Frames some transform could not be given for (kept, status INVALID).
    pub frames_without_pose: usize,
    /// STATUS messages' `code name: message` (the first ones).
    pub statuses: Vec<String>,
    pub bytes: u64,
}

impl StreamCounts {
    fn skip(&mut self, kind: &str, device: &str, reason: &str) {
        self.skipped += 1;
        if self.skip_reasons.len() < MAX_LISTED {
            self.skip_reasons.push(format!("{kind} from `{device}`: {reason}"));
        }
    }
}

/// A session on a stream.
pub struct StreamRun {
    pub frames: Vec<LiveFrame>,
    pub counts: StreamCounts,
    pub ending: Ending,
    /// The received frames' rate (their timestamps), frames/s.
    pub received_rate_hz: f64,
    /// The tracker lag used while frames arrived, s (0 where it is estimated at the end).
    pub live_time_offset_s: f64,
    pub last_live: Option<crate::estimate::image_to_probe::Fit>,
    /// The batch pipeline on the received frames.
    pub final_run: Result<TrackedRun, BatchFault>,
    /// The calibration sent back, or why it was not.
    pub sent: Result<Matrix4<f64>, NotSent>,
    pub volume: Option<VolumeOutcome>,
}

/// Why the received frames gave no calibration.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BatchFault {
    #[error("no image was received")]
    NoImage,
    /// The received frames could not be written (the message names the file).
    #[error("{0}")]
    Write(String),
    /// The batch pipeline refused them (its message).
    #[error("{0}")]
    Run(String),
}

/// Why the calibration was not sent back.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NotSent {
    #[error("not sent: {0}")]
    Ended(String),
    #[error("not sent: no calibration")]
    NoCalibration,
    #[error("{0}")]
    Socket(String),
}

/// Why an IMAGE message's image is not a frame of the stream.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum ImageRefusal {
    #[error("a {w}x{h}x{d} image of scalar type {scalar_type} with {components} component(s): B-scans are 2D 8-bit grey (scalar type 3, 1 component)")]
    Kind {
        w: usize,
        h: usize,
        d: usize,
        scalar_type: u8,
        components: u8,
    },
    #[error("a {w}x{h} image: a frame holds 1 to {MAX_FRAME_PIXELS} pixels (as in a sequence file)")]
    Size { w: usize, h: usize },
    #[error("a {w}x{h} image in a stream of {stream_w}x{stream_h} images")]
    Mismatch {
        w: usize,
        h: usize,
        stream_w: usize,
        stream_h: usize,
    },
}

/// What the live reconstruction did.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VolumeOutcome {
    pub dims: [usize; 3],
    pub spacing_mm: [f64; 3],
    pub origin_mm: [f64; 3],
    pub frames_inserted: usize,
    pub frames_not_inserted: usize,
    pub not_inserted_reasons: Vec<String>,
    pub volumes_sent: usize,
    /// Voxels some pixel reached in the last volume sent.
    pub voxels_reached: usize,
    /// Why sending stopped, if it did.
    pub send_error: Option<String>,
}

/// The session's live state: the received sequence and the calibration.
struct Session<'a> {
    inputs: &'a TrackedInputs,
    sequence: Option<Sequence>,
    /// The first image and its size, until the next confirms it.
    first: Option<(PendingImage, (usize, usize))>,
    state: State<'a>,
    offset_s: f64,
    pending: LagQueue,
    frames: Vec<LiveFrame>,
    start: Instant,
    received_path: PathBuf,
    pairing: Pairing,
    counts: StreamCounts,
    /// The images' timestamps, s.
    times: Vec<f64>,
    volume: Option<LiveVolume>,
    /// Frames of `frames` already offered to the volume.
    volume_cursor: usize,
    volumes_sent: usize,
    volume_device: String,
    volume_error: Option<String>,
}

impl Session<'_> {
    /// Appends a paired image to the sequence and processes it.
    fn take(
        &mut self,
        pixels: &[u8],
        fields: BTreeMap<String, String>,
        received: Instant,
        show: &mut dyn FnMut(&LiveFrame),
    ) {
        let Some(sequence) = self.sequence.as_mut() else { return };
        if let Err(reason) = sequence.push_frame(fields, pixels) {
            self.counts.skip("IMAGE", "received frame", &reason.to_string());
            return;
        }
        let sequence: &Sequence = sequence;
        let work = Instant::now();
        let clip = self
            .inputs
            .clip_rectangle_px
            .unwrap_or([0, 0, sequence.width, sequence.height]);
        let segmentation = segmentation_inputs(self.inputs, clip, None);
        let geometry = pattern_geometry(&segmentation);
        let index = sequence.frames.len() - 1;
        let frame = segment_frame(sequence, index, Role::Calibration, &segmentation, &geometry);
        let this = Arrived {
            frame,
            arrived: received,
            segmentation_ms: work.elapsed().as_secs_f64() * 1e3,
        };
        let latest_s = this.frame.timestamp_s;
        for ready in self.pending.push(this, self.offset_s, latest_s) {
            self.frames.push(finish(
                &mut self.state,
                sequence,
                ready,
                self.offset_s,
                self.start,
                show,
            ));
        }
    }
}

impl<'a> Session<'a> {
    /// A session on nothing received yet.
    fn open(
        inputs: &'a TrackedInputs,
        settings: &StreamSettings,
        staging: &Path,
        offset_s: f64,
    ) -> Result<Session<'a>, SessionError> {
        let stream = &settings.stream;
        let names = [inputs.probe_transform.clone(), inputs.reference_transform.clone()];
        Ok(Session {
            inputs,
            sequence: None,
            first: None,
            state: State::new(inputs),
            offset_s,
            pending: LagQueue::default(),
            frames: Vec::new(),
            start: Instant::now(),
            received_path: staging.join("received.igs.mha"),
            pairing: Pairing::new(&names, stream.max_transform_gap_s),
            counts: StreamCounts::default(),
            times: Vec::new(),
            volume: settings
                .volume
                .as_ref()
                .map(LiveVolume::open)
                .transpose()
                .map_err(SessionError::Volume)?,
            volume_cursor: 0,
            volumes_sent: 0,
            volume_device: settings.volume.as_ref().map(|v| v.device.clone()).unwrap_or_default(),
            volume_error: None,
        })
    }
}

/// Connects, calibrates while frames arrive, then runs the batch calibration on
/// the received frames (written to `staging/received.igs.mha`) and sends it back.
/// `stop` set ends the acquisition (an interrupt).
pub fn run(
    inputs: &TrackedInputs,
    min_frames: usize,
    settings: &StreamSettings,
    staging: &Path,
    stop: &AtomicBool,
    show: &mut dyn FnMut(&LiveFrame),
) -> Result<StreamRun, SessionError> {
    let stream = &settings.stream;
    let offset_s = live_offset_s(inputs)?;
    let mut connection = Reader::start(Connection::open(&settings.address, Duration::from_secs(5))?)?;
    let mut session = Session::open(inputs, settings, staging, offset_s)?;
    let mut last_message = Instant::now();
    let ending = loop {
        if stop.load(Ordering::Relaxed) {
            break Ending::Interrupted;
        }
        if last_message.elapsed().as_secs_f64() >= stream.silence_s {
            break Ending::Silence;
        }
        let (event, read) = match connection.next(Duration::from_millis(50)) {
            Ok(next) => next,
            Err(reason) => break Ending::Broken(reason),
        };
        match event {
            Event::Quiet => continue,
            Event::Closed => break Ending::Closed,
            Event::Cut(reason) => break Ending::Cut(reason),
            Event::Skipped { kind, device, reason } => session.counts.skip(&kind, &device, &reason),
            Event::Message(header, body) => {
                if let Some(ending) = session.message(&header, body, read, stream) {
                    break ending;
                }
                session.drain(false, show);
                session.volume_step(&mut connection, false);
            }
        }
        last_message = Instant::now();
    };
    session.admit_last();
    session.drain(true, show);
    if let Some(sequence) = session.sequence.as_ref() {
        for last in session.pending.drain() {
            let live = finish(&mut session.state, sequence, last, offset_s, session.start, show);
            session.frames.push(live);
        }
    }
    if ending.connected() {
        session.volume_step(&mut connection, true);
    }
    session.counts.bytes = connection.bytes_received();
    let final_run = batch(&session, inputs, min_frames);
    let sent = match (&final_run, ending.connected()) {
        (Ok(run), true) => {
            send_back(&mut connection, &stream.send_device, run).map_err(|e| NotSent::Socket(e.to_string()))
        }
        (Ok(_), false) => Err(NotSent::Ended(ending.describe(stream))),
        (Err(_), _) => Err(NotSent::NoCalibration),
    };
    Ok(StreamRun {
        frames: session.frames,
        counts: session.counts,
        ending,
        received_rate_hz: rate(&session.times),
        live_time_offset_s: offset_s,
        last_live: session.state.fit,
        final_run,
        sent,
        volume: session.volume.as_ref().map(|v| VolumeOutcome {
            dims: v.grid.dims,
            spacing_mm: v.grid.spacing_mm,
            origin_mm: v.grid.origin_mm,
            frames_inserted: v.inserted,
            frames_not_inserted: v.not_inserted,
            not_inserted_reasons: v.not_inserted_reasons.clone(),
            volumes_sent: session.volumes_sent,
            voxels_reached: v.voxels_reached,
            send_error: session.volume_error.clone(),
        }),
    })
}

impl Session<'_> {
    /// Takes one message; the acquisition's end if it is one.
    fn message(&mut self, header: &Header, body: Body, read: Instant, stream: &LiveStream) -> Option<Ending> {
        let key = format!("{} {}", header.kind, header.device);
        *self.counts.messages.entry(key.clone()).or_default() += 1;
        match body {
            Body::Image(image) if header.device == stream.image_device => {
                self.counts.images_received += 1;
                let admitted = match self.admit(header, image, read) {
                    Ok(admitted) => admitted,
                    Err(refusal) => {
                        self.counts.skip("IMAGE", &header.device, &refusal.to_string());
                        return None;
                    }
                };
                if self.sequence.as_ref().is_some_and(|s| {
                    (s.frames.len() + self.pairing.waiting() + admitted.len()) * s.width * s.height
                        > MAX_RECEIVED_PIXELS
                }) {
                    return Some(Ending::FrameLimit);
                }
                for image in admitted {
                    self.times.push(image.timestamp_s);
                    self.pairing.add_image(image);
                }
            }
            Body::Transform(m) if self.pairing.wants(&header.device) => {
                if let Err(refused) = self.pairing.add_transform(&header.device, header.timestamp_s, m) {
                    self.counts.skip("TRANSFORM", &header.device, &refused.0);
                }
            }
            Body::String(_) if header.device == stream.end_device => return Some(Ending::EndMessage),
            Body::Status { code, name, message } => {
                if self.counts.statuses.len() < MAX_LISTED {
                    self.counts.statuses.push(format!("{code} {name}: {message}"));
                }
            }
            _ => *self.counts.ignored.entry(key).or_default() += 1,
        }
        None
    }

    /// Offers the frames finished since the last call to the live volume, and
    /// sends it when it is due (or, at the `end`, when frames came in since).
    fn volume_step(&mut self, connection: &mut Reader, end: bool) {
        let (Some(volume), Some(sequence)) = (self.volume.as_mut(), self.sequence.as_ref()) else {
            return;
        };
        if self.volume_error.is_some() {
            return;
        }
        let names = [
            self.inputs.probe_transform.as_str(),
            self.inputs.reference_transform.as_str(),
        ];
        let calibration = self.state.fit.as_ref().map(|f| f.image_to_probe.matrix());
        let mut due = false;
        for frame in &self.frames[self.volume_cursor..] {
            due |= volume.insert(sequence, frame.index, names, calibration.as_ref());
        }
        self.volume_cursor = self.frames.len();
        if !(due || (end && volume.unsent() > 0)) {
            return;
        }
        let Some(snapshot) = volume.snapshot() else { return };
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map(|d| d.as_secs_f64())
            .unwrap_or(0.0);
        match connection.send(&volume_message(&self.volume_device, now, &snapshot)) {
            Ok(()) => self.volumes_sent += 1,
            Err(e) => self.volume_error = Some(e.to_string()),
        }
    }

    /// Processes the images whose transforms are known (all, once `ended`).
    fn drain(&mut self, ended: bool, show: &mut dyn FnMut(&LiveFrame)) {
        for paired in self.pairing.ready(ended) {
            self.counts.frames += 1;
            self.counts.frames_without_pose += usize::from(!paired.missing.is_empty());
            self.take(&paired.image.pixels, paired.fields, paired.image.received, show);
        }
    }
}

impl Session<'_> {
    /// The images an IMAGE message lets into the stream, oldest first. The
    /// stream's frame size is set by two images in a row of one size: a lone
    /// first image of another size (a stray, an oversized one) is skipped with
    /// its reason instead of fixing the size every later frame is held to.
    fn admit(
        &mut self,
        header: &Header,
        image: message::Image,
        read: Instant,
    ) -> Result<Vec<PendingImage>, ImageRefusal> {
        let (w, h) = (image.size[0], image.size[1]);
        if image.scalar_type != 3 || image.components != 1 || image.size[2] != 1 {
            return Err(ImageRefusal::Kind {
                w,
                h,
                d: image.size[2],
                scalar_type: image.scalar_type,
                components: image.components,
            });
        }
        if w == 0 || h == 0 || w.saturating_mul(h) > MAX_FRAME_PIXELS {
            return Err(ImageRefusal::Size { w, h });
        }
        let this = PendingImage {
            timestamp_s: header.timestamp_s,
            pixels: image.pixels,
            received: read,
        };
        if let Some(s) = &self.sequence {
            if (s.width, s.height) != (w, h) {
                return Err(ImageRefusal::Mismatch {
                    w,
                    h,
                    stream_w: s.width,
                    stream_h: s.height,
                });
            }
            return Ok(vec![this]);
        }
        match self.first.take() {
            Some((first, size)) if size == (w, h) => {
                self.sequence = Some(Sequence::empty(&self.received_path, w, h));
                Ok(vec![first, this])
            }
            Some((_, (fw, fh))) => {
                self.counts.skip(
                    "IMAGE",
                    &header.device,
                    &format!("a {fw}x{fh} first image, not followed by another of its size (the next is {w}x{h})"),
                );
                self.first = Some((this, (w, h)));
                Ok(Vec::new())
            }
            None => {
                self.first = Some((this, (w, h)));
                Ok(Vec::new())
            }
        }
    }

    /// A stream of one image: it starts the sequence at the end.
    fn admit_last(&mut self) {
        if let (None, Some((first, (w, h)))) = (&self.sequence, self.first.take()) {
            self.sequence = Some(Sequence::empty(&self.received_path, w, h));
            self.times.push(first.timestamp_s);
            self.pairing.add_image(first);
        }
    }
}

/// The received frames written out and calibrated in batch.
fn batch(session: &Session<'_>, inputs: &TrackedInputs, min_frames: usize) -> Result<TrackedRun, BatchFault> {
    let sequence = session.sequence.as_ref().ok_or(BatchFault::NoImage)?;
    crate::io::fs::write_atomic(&session.received_path, &sequence.to_file_bytes())
        .map_err(|e| BatchFault::Write(e.to_string()))?;
    let mut received = inputs.clone();
    received.calibration_sequence = session.received_path.clone();
    tracked::run(&received, min_frames).map_err(|e| BatchFault::Run(e.to_string()))
}

/// Sends the calibration as a TRANSFORM message.
fn send_back(connection: &mut Reader, device: &str, run: &TrackedRun) -> Result<Matrix4<f64>, IgtlError> {
    let m = run.fit.image_to_probe.matrix();
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0);
    connection.send(&message::encode("TRANSFORM", device, now, &message::transform_body(&m)))?;
    Ok(m)
}

/// Frames per second from the images' timestamps.
fn rate(times: &[f64]) -> f64 {
    match (times.first(), times.last()) {
        (Some(a), Some(b)) if b > a && times.len() > 1 => (times.len() - 1) as f64 / (b - a),
        _ => 0.0,
    }
}
