//! OpenIGTLink, the network protocol of PlusServer and 3D Slicer: message
//! encoding and decoding, and a client connection.

pub mod connection;
pub mod message;
pub mod reader;
