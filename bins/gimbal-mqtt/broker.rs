//! The door's connection to the broker through `rumqttc`, MQTT 3.1.1
//! (OASIS mqtt-v3.1.1) or 5 (OASIS mqtt-v5.0) as configured, behind one
//! small surface: publish, subscribe, and the next event of the
//! connection. A clean session every time (3.1.1 "Clean Session" 1, 5
//! "Clean Start" 1 with no session expiry): the broker keeps no command
//! for the door while it is away, so none runs late. The last will is
//! `offline`, retained, on the site's status topic.

use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use rumqttc::{QoS, TlsConfiguration, Transport};

use crate::config::{Broker, BrokerTls, Version};

/// The largest MQTT packet the door takes from the broker: 5 tells the
/// broker (CONNECT's Maximum Packet Size, which it then never sends past);
/// 3.1.1 closes the connection on a larger one, before reading it.
pub const MAX_PACKET: usize = 256 * 1024;

/// Requests (publishes, subscriptions) waiting for the connection.
const REQUESTS: usize = 1024;

/// rustls's client configuration of `tls` (ring, as gcud's links).
pub fn rustls_config(tls: &BrokerTls) -> Result<Arc<tokio_rustls::rustls::ClientConfig>, String> {
    let identity = tls.identity.as_ref().map(|(c, k)| (c.as_path(), k.as_path()));
    let connector = sagebrush_host::tls::connector(&tls.ca, identity).map_err(|e| e.to_string())?;
    Ok(Arc::clone(connector.config()))
}

/// One event of the connection, as the door needs it.
#[derive(Debug)]
pub enum Event {
    /// The broker accepted the connection (CONNACK).
    Connected,
    /// A message on a subscribed topic.
    Message {
        topic: String,
        payload: Bytes,
        retain: bool,
    },
    /// Anything else (acknowledgements, pings).
    Other,
}

/// A client of the broker (cheap to clone).
#[derive(Clone, Debug)]
pub enum Client {
    V311(rumqttc::AsyncClient),
    V5(rumqttc::v5::AsyncClient),
}

/// The connection's event loop: polled by one task, which reconnects.
pub enum EventLoop {
    V311(Box<rumqttc::EventLoop>),
    V5(Box<rumqttc::v5::EventLoop>),
}

impl std::fmt::Debug for EventLoop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("EventLoop")
    }
}

/// The client and its event loop for `broker`, with the last will
/// `will_payload` retained on `will_topic`. Nothing connects until the
/// event loop is polled.
pub fn connect(broker: &Broker, will_topic: &str, will_payload: &str) -> Result<(Client, EventLoop), String> {
    let transport = match &broker.tls {
        Some(tls) => Transport::tls_with_config(TlsConfiguration::Rustls(rustls_config(tls)?)),
        None => Transport::tcp(),
    };
    Ok(match broker.version {
        Version::V311 => {
            let mut o = rumqttc::MqttOptions::new(&broker.client_id, &broker.host, broker.port);
            o.set_keep_alive(broker.keep_alive)
                .set_clean_session(true)
                .set_max_packet_size(MAX_PACKET, MAX_PACKET)
                .set_request_channel_capacity(REQUESTS)
                .set_transport(transport)
                .set_last_will(rumqttc::LastWill::new(will_topic, will_payload, QoS::AtLeastOnce, true));
            if let Some((user, password)) = &broker.credentials {
                o.set_credentials(user, password);
            }
            let (client, events) = rumqttc::AsyncClient::new(o, REQUESTS);
            (Client::V311(client), EventLoop::V311(Box::new(events)))
        }
        Version::V5 => {
            use rumqttc::v5::mqttbytes::v5::LastWill;
            let mut o = rumqttc::v5::MqttOptions::new(&broker.client_id, &broker.host, broker.port);
            o.set_keep_alive(broker.keep_alive)
                .set_clean_start(true)
                .set_session_expiry_interval(None)
                .set_max_packet_size(Some(MAX_PACKET as u32))
                .set_request_channel_capacity(REQUESTS)
                .set_transport(transport)
                .set_last_will(LastWill::new(
                    will_topic,
                    will_payload,
                    rumqttc::v5::mqttbytes::QoS::AtLeastOnce,
                    true,
                    None,
                ));
            if let Some((user, password)) = &broker.credentials {
                o.set_credentials(user, password);
            }
            let (client, events) = rumqttc::v5::AsyncClient::new(o, REQUESTS);
            (Client::V5(client), EventLoop::V5(Box::new(events)))
        }
    })
}

fn qos5(q: QoS) -> rumqttc::v5::mqttbytes::QoS {
    match q {
        QoS::AtMostOnce => rumqttc::v5::mqttbytes::QoS::AtMostOnce,
        QoS::AtLeastOnce => rumqttc::v5::mqttbytes::QoS::AtLeastOnce,
        QoS::ExactlyOnce => rumqttc::v5::mqttbytes::QoS::ExactlyOnce,
    }
}

impl Client {
    /// Publishes at QoS 1, waiting for room among the requests.
    pub async fn publish(&self, topic: String, retain: bool, payload: Vec<u8>) -> Result<(), String> {
        match self {
            Client::V311(c) => c
                .publish(topic, QoS::AtLeastOnce, retain, payload)
                .await
                .map_err(|e| e.to_string()),
            Client::V5(c) => c
                .publish(topic, qos5(QoS::AtLeastOnce), retain, payload)
                .await
                .map_err(|e| e.to_string()),
        }
    }

    /// Publishes at QoS 1 if there is room among the requests now;
    /// `false` when there is none (the caller tries again later, or drops
    /// what no one waits for).
    pub fn try_publish(&self, topic: String, retain: bool, payload: Vec<u8>) -> bool {
        match self {
            Client::V311(c) => c.try_publish(topic, QoS::AtLeastOnce, retain, payload).is_ok(),
            Client::V5(c) => c.try_publish(topic, qos5(QoS::AtLeastOnce), retain, payload).is_ok(),
        }
    }

    /// Subscribes to `filters` at QoS 1.
    pub async fn subscribe(&self, filters: &[String]) -> Result<(), String> {
        for f in filters {
            let r = match self {
                Client::V311(c) => c
                    .subscribe(f.clone(), QoS::AtLeastOnce)
                    .await
                    .map_err(|e| e.to_string()),
                Client::V5(c) => c
                    .subscribe(f.clone(), qos5(QoS::AtLeastOnce))
                    .await
                    .map_err(|e| e.to_string()),
            };
            r?;
        }
        Ok(())
    }

    /// DISCONNECT (no last will: the door said `offline` itself).
    pub async fn disconnect(&self) {
        let _ = match self {
            Client::V311(c) => c.disconnect().await.map_err(|e| e.to_string()),
            Client::V5(c) => c.disconnect().await.map_err(|e| e.to_string()),
        };
    }
}

impl EventLoop {
    /// The next event; an error is a lost (or refused) connection, and
    /// the next call connects again.
    pub async fn next(&mut self) -> Result<Event, String> {
        match self {
            EventLoop::V311(e) => match e.poll().await.map_err(|e| e.to_string())? {
                rumqttc::Event::Incoming(rumqttc::Packet::ConnAck(_)) => Ok(Event::Connected),
                rumqttc::Event::Incoming(rumqttc::Packet::Publish(p)) => Ok(Event::Message {
                    topic: p.topic,
                    payload: p.payload,
                    retain: p.retain,
                }),
                _ => Ok(Event::Other),
            },
            EventLoop::V5(e) => {
                use rumqttc::v5::mqttbytes::v5::{ConnectReturnCode, Packet};
                match e.poll().await.map_err(|e| e.to_string())? {
                    rumqttc::v5::Event::Incoming(Packet::ConnAck(a)) if a.code == ConnectReturnCode::Success => {
                        Ok(Event::Connected)
                    }
                    rumqttc::v5::Event::Incoming(Packet::ConnAck(a)) => {
                        Err(format!("the broker refused: {:?}", a.code))
                    }
                    rumqttc::v5::Event::Incoming(Packet::Publish(p)) => Ok(Event::Message {
                        topic: String::from_utf8_lossy(&p.topic).into_owned(),
                        payload: p.payload,
                        retain: p.retain,
                    }),
                    _ => Ok(Event::Other),
                }
            }
        }
    }
}

/// The wait before connecting again after `failures` failures in a row:
/// doubling from `min` up to `max`.
pub fn back_off(min: Duration, max: Duration, failures: u32) -> Duration {
    min.saturating_mul(1u32 << failures.min(16)).min(max)
}
