//! MAVLink on the wire and the endpoints it travels: frames (`wire`),
//! signing (`signing`), this system and its peers (`net`), UDP endpoints
//! and the outbox (`link`), TCP and serial byte streams (`stream`), each
//! configured endpoint started as its own task (`endpoints`).

pub mod endpoints;
pub mod link;
pub mod net;
pub mod signing;
pub mod stream;
pub mod wire;
