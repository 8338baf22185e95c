//! OpenIGTLink, the network protocol of PlusServer and 3D Slicer: message
//! encoding and decoding, and a client connection.

pub mod connection;
pub mod message;
pub mod reader;

/// Why an OpenIGTLink connection, stream or message could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IgtlError {
    /// The server could not be reached at `address`.
    #[error("{address}: {reason}")]
    Connect { address: String, reason: String },
    /// The socket failed (`what`: receiving, sending, cloning it).
    #[error("{what}: {reason}")]
    Socket { what: &'static str, reason: String },
    /// Bytes that cannot be framed as messages: nothing after them can be read.
    #[error("{0}")]
    Unframed(String),
    /// A framed message whose body is not what its type and sizes say (it is
    /// skipped; the stream goes on).
    #[error("{0}")]
    Malformed(String),
}

impl IgtlError {
    /// A socket error of `what`.
    pub fn socket(what: &'static str) -> impl Fn(std::io::Error) -> IgtlError {
        move |e| IgtlError::Socket {
            what,
            reason: e.to_string(),
        }
    }
}
