//! The I/O tasks of the configured ports and links (module `io`), started
//! and stopped one by one so that a reload can change them.

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;

use sagebrush_gcu::LinkId;
use sagebrush_host::capture::CaptureSwitch;
use tokio::net::TcpListener;
use tokio::sync::mpsc;
use tokio::task::JoinHandle;
use tracing::info;

use super::StartError;
use crate::admission::Connections;
use crate::config::{Link, LinkTransport, Port};
use crate::io::{self, IoEvent};
use crate::shard::Shards;

/// The I/O tasks of the configured ports and links, so that a reload can
/// close and open them one by one.
pub(super) struct Tasks {
    pub(super) events: mpsc::Sender<IoEvent>,
    pub(super) connections: Arc<Connections>,
    pub(super) ports: HashMap<u8, JoinHandle<()>>,
    pub(super) links: BTreeMap<String, JoinHandle<()>>,
    /// The bound listeners, by link name, with the address configured (a
    /// reload hands one over to the link that takes its address).
    pub(super) listeners: BTreeMap<String, (std::net::SocketAddr, Arc<TcpListener>)>,
    /// `[capture]`: every port and link task taps its bytes here.
    pub(super) capture: Arc<CaptureSwitch>,
    /// The port threads (`[gcu] threads`).
    pub(super) shards: Shards,
}

impl Tasks {
    /// The listener of a `listen` link, bound now (`None` for other links):
    /// the one a link closing in the same reload holds at that address, or
    /// a new one (an address in use is an error).
    pub(super) async fn bind(&self, link: &Link, closing: &[&str]) -> Result<Option<Arc<TcpListener>>, StartError> {
        let LinkTransport::Listen(addr) = link.transport else {
            return Ok(None);
        };
        let held = self
            .listeners
            .iter()
            .find(|(name, (at, _))| *at == addr && addr.port() != 0 && closing.contains(&name.as_str()));
        if let Some((_, (_, listener))) = held {
            return Ok(Some(listener.clone()));
        }
        let listener = TcpListener::bind(addr).await.map_err(|error| StartError::Listen {
            link: link.name.clone(),
            addr,
            error,
        })?;
        Ok(Some(Arc::new(listener)))
    }

    /// Starts a link; a `listen` link accepts on `listener` (from [`Tasks::bind`]).
    pub(super) fn start_link(&mut self, link: &Link, id: LinkId, listener: Option<Arc<TcpListener>>) {
        let task = match (link.transport.clone(), listener) {
            (LinkTransport::Listen(addr), Some(listener)) => {
                info!(link = %link.name, addr = %listener.local_addr().unwrap_or(addr), "listening");
                self.listeners.insert(link.name.clone(), (addr, listener.clone()));
                let connections = self.connections.clone();
                tokio::spawn(io::accept_loop(
                    link.clone(),
                    listener,
                    connections,
                    self.events.clone(),
                    self.capture.clone(),
                ))
            }
            _ => tokio::spawn(io::run_link(
                id,
                link.clone(),
                self.events.clone(),
                self.capture.clone(),
            )),
        };
        if let Some(old) = self.links.insert(link.name.clone(), task) {
            old.abort();
        }
    }

    pub(super) fn stop_link(&mut self, name: &str) {
        self.listeners.remove(name);
        if let Some(task) = self.links.remove(name) {
            task.abort();
        }
    }

    /// Starts a port's task: on the port thread it is placed on (module
    /// `shard`), else on the router task's.
    pub(super) fn start_port(&mut self, port: &Port) {
        let (events, capture) = (self.events.clone(), self.capture.clone());
        let task = match self.shards.place(port.id) {
            Some((thread, relay)) => thread.spawn(io::run_port(port.clone(), events, capture, Some(relay))),
            None => tokio::spawn(io::run_port(port.clone(), events, capture, None)),
        };
        if let Some(old) = self.ports.insert(port.id, task) {
            old.abort();
        }
    }

    pub(super) fn stop_port(&mut self, id: u8) {
        if let Some(task) = self.ports.remove(&id) {
            task.abort();
        }
    }
}
