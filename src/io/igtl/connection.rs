//! An OpenIGTLink client connection: messages framed from a TCP stream, each
//! body's CRC checked, with bounded memory (a body announced above
//! [`MAX_BODY_BYTES`] ends the session: the stream cannot be trusted past it).
//! A message that is framed but wrong (bad CRC, a body that contradicts its own
//! sizes) is returned as a skip with its reason; the stream goes on after it.

use std::io::{Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::{Duration, Instant};

use super::message::{decode, Body, Header, HEADER_BYTES};
use super::IgtlError;

/// Largest body accepted: 256 MiB (a 4096x4096 float image is 64 MiB).
pub const MAX_BODY_BYTES: u64 = 1 << 28;

/// What one wait on the stream gave.
#[derive(Debug, Clone, PartialEq)]
pub enum Event {
    Message(Header, Body),
    /// A framed message that could not be used: its type, device and why.
    Skipped {
        kind: String,
        device: String,
        reason: String,
    },
    /// Nothing complete arrived within the wait.
    Quiet,
    /// The server closed the connection between messages.
    Closed,
    /// The server closed the connection inside a message.
    Cut(String),
}

pub struct Connection {
    stream: TcpStream,
    buffer: Vec<u8>,
    /// Bytes received in all.
    pub bytes_received: u64,
}

impl Connection {
    /// Connects to `address` (`HOST:PORT`) within `timeout`.
    pub fn open(address: &str, timeout: Duration) -> Result<Connection, IgtlError> {
        let addresses: Vec<_> = address
            .to_socket_addrs()
            .map_err(|e| IgtlError::Connect {
                address: address.to_string(),
                reason: format!("not a HOST:PORT address ({e})"),
            })?
            .collect();
        let mut last = IgtlError::Connect {
            address: address.to_string(),
            reason: "resolves to no address".into(),
        };
        for a in addresses {
            match TcpStream::connect_timeout(&a, timeout) {
                Ok(stream) => {
                    let _ = stream.set_nodelay(true);
                    stream
                        .set_write_timeout(Some(Duration::from_secs(10)))
                        .map_err(IgtlError::socket("setting the socket's timeout"))?;
                    return Ok(Connection {
                        stream,
                        buffer: Vec::new(),
                        bytes_received: 0,
                    });
                }
                Err(e) => {
                    last = IgtlError::Connect {
                        address: address.to_string(),
                        reason: format!("cannot connect ({e})"),
                    }
                }
            }
        }
        Err(last)
    }

    /// The next message, a skip, or what ended the wait. An error ends the
    /// session (a header that cannot be framed, a body above the limit, a socket
    /// error).
    /// The wait is bounded as a whole: a server that trickles a message a byte
    /// at a time gives [`Event::Quiet`] after `wait`, not a read that never ends.
    pub fn next(&mut self, wait: Duration) -> Result<Event, IgtlError> {
        let deadline = Instant::now() + wait;
        loop {
            if let Some(event) = self.take()? {
                return Ok(event);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(Event::Quiet);
            }
            self.stream
                .set_read_timeout(Some(left.max(Duration::from_millis(1))))
                .map_err(IgtlError::socket("receiving"))?;
            let mut chunk = [0u8; 1 << 16];
            match self.stream.read(&mut chunk) {
                Ok(0) => {
                    return Ok(if self.buffer.is_empty() {
                        Event::Closed
                    } else {
                        Event::Cut(self.cut_reason())
                    })
                }
                Ok(n) => {
                    self.bytes_received += n as u64;
                    self.buffer.extend_from_slice(&chunk[..n]);
                }
                Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                    return Ok(Event::Quiet)
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => return Ok(Event::Quiet),
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {
                    return Ok(if self.buffer.is_empty() {
                        Event::Closed
                    } else {
                        Event::Cut(self.cut_reason())
                    })
                }
                Err(e) => return Err(IgtlError::socket("receiving")(e)),
            }
        }
    }

    /// Why the bytes left in the buffer are not a message.
    fn cut_reason(&self) -> String {
        match self.header() {
            Ok(Some(h)) => format!(
                "the connection closed {} bytes into the {}-byte body of a {} message from `{}`",
                self.buffer.len() - HEADER_BYTES,
                h.body_bytes,
                h.kind,
                h.device
            ),
            _ => format!(
                "the connection closed {} bytes into a {HEADER_BYTES}-byte message header",
                self.buffer.len()
            ),
        }
    }

    fn header(&self) -> Result<Option<Header>, IgtlError> {
        if self.buffer.len() < HEADER_BYTES {
            return Ok(None);
        }
        let bytes: &[u8; HEADER_BYTES] = self.buffer[..HEADER_BYTES]
            .try_into()
            .map_err(|_| IgtlError::Unframed("a header of the wrong length".into()))?;
        let header = Header::parse(bytes)?;
        if header.body_bytes > MAX_BODY_BYTES {
            return Err(IgtlError::Unframed(format!(
                "a {} message from `{}` announces a body of {} bytes, above the limit of {MAX_BODY_BYTES}: the stream cannot be framed past it",
                header.kind, header.device, header.body_bytes
            )));
        }
        Ok(Some(header))
    }

    /// A whole message from the buffer, if one is there.
    fn take(&mut self) -> Result<Option<Event>, IgtlError> {
        let Some(header) = self.header()? else {
            return Ok(None);
        };
        let end = HEADER_BYTES + header.body_bytes as usize;
        if self.buffer.len() < end {
            return Ok(None);
        }
        let body = &self.buffer[HEADER_BYTES..end];
        let crc = super::message::crc64(body);
        let event = if crc != header.crc {
            Event::Skipped {
                kind: header.kind.clone(),
                device: header.device.clone(),
                reason: format!(
                    "CRC-64 of the {}-byte body is {crc:016x}, the header says {:016x}",
                    body.len(),
                    header.crc
                ),
            }
        } else {
            match decode(&header, body) {
                Ok(b) => Event::Message(header, b),
                Err(e) => Event::Skipped {
                    kind: header.kind.clone(),
                    device: header.device.clone(),
                    reason: e.to_string(),
                },
            }
        };
        self.buffer.drain(..end);
        Ok(Some(event))
    }

    /// A second handle on the socket, for sending while another thread reads.
    pub fn sender(&self) -> Result<Sender, IgtlError> {
        self.stream
            .try_clone()
            .map(|stream| Sender { stream })
            .map_err(IgtlError::socket("cloning the socket"))
    }

    /// Sends a whole encoded message.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), IgtlError> {
        self.stream
            .write_all(bytes)
            .and_then(|_| self.stream.flush())
            .map_err(IgtlError::socket("sending"))
    }
}

/// The sending side of a connection.
pub struct Sender {
    stream: TcpStream,
}

impl Sender {
    /// Closes the connection both ways: a read blocked on it returns at once.
    pub fn shutdown(&self) {
        let _ = self.stream.shutdown(std::net::Shutdown::Both);
    }

    /// Sends a whole encoded message.
    pub fn send(&mut self, bytes: &[u8]) -> Result<(), IgtlError> {
        self.stream
            .write_all(bytes)
            .and_then(|_| self.stream.flush())
            .map_err(IgtlError::socket("sending"))
    }
}
