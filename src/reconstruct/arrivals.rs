//! Frames handed over one by one by the thread decoding them, to the threads
//! pasting them: a pasting thread that needs a frame not yet decoded waits for it.

use std::sync::{Condvar, Mutex, PoisonError};

use super::paste::Frames;

/// Decoded frames, in the sequence's order, and the frames pasted (their
/// indices in the sequence, in paste order).
pub struct Arrivals<'a, T> {
    pasted: Vec<usize>,
    state: Mutex<State<'a, T>>,
    changed: Condvar,
}

struct State<'a, T> {
    decoded: Vec<&'a [T]>,
    /// No frame will come after `decoded` (the decoder has finished or failed).
    closed: bool,
}

impl<'a, T> Arrivals<'a, T> {
    /// Nothing decoded yet; `pasted`: the sequence index of each frame pasted.
    pub fn new(pasted: Vec<usize>) -> Self {
        Arrivals {
            pasted,
            state: Mutex::new(State {
                decoded: Vec::new(),
                closed: false,
            }),
            changed: Condvar::new(),
        }
    }

    /// The next frame of the sequence is decoded.
    pub fn arrive(&self, frame: &'a [T]) {
        let mut state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        state.decoded.push(frame);
        self.changed.notify_all();
    }

    /// No more frames will come (whether or not all did); waiting ends.
    pub fn close(&self) {
        self.state.lock().unwrap_or_else(PoisonError::into_inner).closed = true;
        self.changed.notify_all();
    }

    /// A guard that closes the arrivals when dropped (also when the decoder panics).
    pub fn closer(&self) -> Closer<'_, 'a, T> {
        Closer(self)
    }
}

/// Closes its [`Arrivals`] when dropped.
pub struct Closer<'s, 'a, T>(&'s Arrivals<'a, T>);

impl<T> Drop for Closer<'_, '_, T> {
    fn drop(&mut self) {
        self.0.close();
    }
}

impl<T: Sync> Frames<T> for Arrivals<'_, T> {
    fn pixels(&self, k: usize) -> Option<&[T]> {
        let index = *self.pasted.get(k)?;
        let mut state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        loop {
            if let Some(&frame) = state.decoded.get(index) {
                return Some(frame);
            }
            if state.closed {
                return None;
            }
            state = self.changed.wait(state).unwrap_or_else(PoisonError::into_inner);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_waiting_reader_gets_its_frame_or_nothing_once_closed() {
        let frames: Vec<Vec<u8>> = (0..4u8).map(|k| vec![k; 3]).collect();
        let arrivals = Arrivals::new(vec![1, 3]);
        std::thread::scope(|s| {
            let reader = s.spawn(|| {
                (
                    arrivals.pixels(0).map(<[u8]>::to_vec),
                    arrivals.pixels(1).map(<[u8]>::to_vec),
                )
            });
            let _close = arrivals.closer();
            for frame in &frames[..3] {
                std::thread::sleep(std::time::Duration::from_millis(5));
                arrivals.arrive(frame);
            }
            drop(_close);
            let (first, second) = reader.join().expect("the reader ends");
            assert_eq!(first, Some(vec![1, 1, 1]));
            assert_eq!(second, None, "frame 3 never came");
        });
    }
}
