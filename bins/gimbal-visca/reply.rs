//! Where a message's replies go: back to the datagram's source address and
//! port (VISCA over IP, its sequence number echoed; or raw VISCA on UDP),
//! or down the TCP connection it came on. Sending never waits: a UDP
//! socket that cannot take a reply now, or a TCP client that reads none,
//! loses it (the client asks again; a stalled TCP client is closed).

use std::net::SocketAddr;
use std::sync::Arc;

use tokio::net::UdpSocket;
use tokio::sync::mpsc;

use crate::framing::{self, payload_type};

/// The client a message came from, and who the door acts for at gcud.
#[derive(Clone, Debug)]
pub struct Replier {
    pub to: Out,
    /// The client's address (for logs).
    pub peer: SocketAddr,
    /// The user the door acts for at gcud (`[[client]]`), or `None`: itself.
    pub user: Option<Arc<str>>,
}

#[derive(Clone, Debug)]
pub enum Out {
    /// VISCA over IP: the reply carries `sequence`.
    Ip { socket: Arc<UdpSocket>, sequence: u32 },
    /// Raw VISCA in a datagram.
    RawUdp { socket: Arc<UdpSocket> },
    /// Raw VISCA on a TCP connection, through its writer's bounded queue.
    Tcp(mpsc::Sender<Vec<u8>>),
}

impl Replier {
    /// Sends the VISCA reply `message` (`90 ... FF`).
    pub fn send(&self, message: &[u8]) {
        match &self.to {
            Out::Ip { socket, sequence } => {
                let _ = socket.try_send_to(&framing::encode(payload_type::REPLY, *sequence, message), self.peer);
            }
            Out::RawUdp { socket } => {
                let _ = socket.try_send_to(message, self.peer);
            }
            Out::Tcp(tx) => {
                let _ = tx.try_send(message.to_vec());
            }
        }
    }
}
