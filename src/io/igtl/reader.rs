//! A connection read on its own thread, so that the socket is drained while
//! frames are processed (a server's send does not wait on the client's work).
//! The messages read and not yet taken are bounded by [`MAX_QUEUED_BYTES`]:
//! past it the thread stops reading and the server's sends wait.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::connection::{Connection, Event, Sender};
use super::IgtlError;

/// Bytes of messages read ahead of the processing: 512 MiB (a thousand 820x616 frames).
pub const MAX_QUEUED_BYTES: u64 = 1 << 29;

pub struct Reader {
    events: Receiver<(Result<Event, IgtlError>, Instant)>,
    queued: Arc<AtomicU64>,
    received: Arc<AtomicU64>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    sender: Sender,
}

fn size(event: &Event) -> u64 {
    match event {
        Event::Message(h, _) => h.body_bytes,
        _ => 0,
    }
}

impl Reader {
    /// Starts reading `connection` on a thread.
    pub fn start(mut connection: Connection) -> Result<Reader, IgtlError> {
        let sender = connection.sender()?;
        let (tx, events) = channel();
        let queued = Arc::new(AtomicU64::new(0));
        let received = Arc::new(AtomicU64::new(0));
        let stop = Arc::new(AtomicBool::new(false));
        let (q, r, s) = (Arc::clone(&queued), Arc::clone(&received), Arc::clone(&stop));
        let thread = std::thread::spawn(move || loop {
            let event = connection.next(Duration::from_millis(50));
            r.store(connection.bytes_received, Ordering::Relaxed);
            let last = !matches!(event, Ok(Event::Message(..) | Event::Skipped { .. } | Event::Quiet));
            if let Ok(Event::Quiet) = event {
                if s.load(Ordering::Relaxed) {
                    return;
                }
                continue;
            }
            let bytes = event.as_ref().map(size).unwrap_or(0);
            q.fetch_add(bytes, Ordering::Relaxed);
            if tx.send((event, Instant::now())).is_err() || last {
                return;
            }
            while q.load(Ordering::Relaxed) > MAX_QUEUED_BYTES && !s.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(1));
            }
            if s.load(Ordering::Relaxed) {
                return;
            }
        });
        Ok(Reader {
            events,
            queued,
            received,
            stop,
            thread: Some(thread),
            sender,
        })
    }

    /// The next event and when it was read off the socket, or [`Event::Quiet`]
    /// after `wait`.
    pub fn next(&self, wait: Duration) -> Result<(Event, Instant), IgtlError> {
        match self.events.recv_timeout(wait) {
            Ok((event, read)) => {
                let bytes = event.as_ref().map(size).unwrap_or(0);
                self.queued.fetch_sub(bytes, Ordering::Relaxed);
                event.map(|e| (e, read))
            }
            Err(RecvTimeoutError::Timeout) => Ok((Event::Quiet, Instant::now())),
            Err(RecvTimeoutError::Disconnected) => Ok((Event::Closed, Instant::now())),
        }
    }

    /// Bytes received so far.
    pub fn bytes_received(&self) -> u64 {
        self.received.load(Ordering::Relaxed)
    }

    /// Sends a whole encoded message on the same connection.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), IgtlError> {
        self.sender.send(bytes)
    }
}

/// How long dropping a [`Reader`] waits for its thread once the socket is shut.
const JOIN_DEADLINE: Duration = Duration::from_secs(2);

impl Drop for Reader {
    /// Stops the thread: the flag, then the socket shut both ways (a read
    /// blocked on it returns); a thread still running after [`JOIN_DEADLINE`]
    /// is left to end on its own rather than waited on without a bound.
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.sender.shutdown();
        if let Some(t) = self.thread.take() {
            let deadline = Instant::now() + JOIN_DEADLINE;
            while !t.is_finished() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(5));
            }
            if t.is_finished() {
                let _ = t.join();
            }
        }
    }
}
