//! The receive thread of a link: it establishes the link (accepting the peer of a `tcpin:`
//! server), makes it available for sending, and hands every decoded message to its owner's
//! handler until stopped. Both ends use it: the controller feeds the autopilot's state, the
//! simulated vehicle its inbox.
//!
//! On simulated time a link is received *inline* instead ([`LinkReceiver::inline`]): no
//! thread, the owner drains what has arrived at the start of each of its turns
//! ([`LinkReceiver::pump`]), so what a turn sees does not depend on when a thread ran.
//! Inline links are UDP (or serial): a datagram sent on the loopback is in the receiver's
//! socket when the send returns.

use crate::link::{LINK_POLL, LinkError, MavLink, PendingLink, Received};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::thread::JoinHandle;

/// The handler of an inline receiver.
type Handler = Box<dyn FnMut(Received) -> ControlFlow<()> + Send>;

/// A link and the thread that receives on it (or its owner, inline). Dropping it stops and
/// joins the thread.
pub struct LinkReceiver {
    link: Arc<OnceLock<MavLink>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    /// Inline: the handler [`LinkReceiver::pump`] calls; `None` once it broke.
    inline: Option<Handler>,
}

impl core::fmt::Debug for LinkReceiver {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("LinkReceiver")
            .field("established", &self.link.get().is_some())
            .field("thread", &self.thread.is_some())
            .field("inline", &self.inline.is_some())
            .finish()
    }
}

impl LinkReceiver {
    /// Spawn the thread `name`: it establishes `pending`, then calls `on_message` with
    /// every message received (MAVLink 1 or 2) until [`LinkReceiver::stop`] or until `on_message` returns
    /// [`ControlFlow::Break`]. Undecodable bytes are skipped; after a transport error the
    /// thread waits [`LINK_POLL`] before it reads again (a closed TCP peer does not make it
    /// spin). When the link cannot be established the thread writes
    /// `"{failure_context}: {error}"` to stderr and ends; [`LinkReceiver::link`] stays
    /// `None` then.
    pub fn spawn<F>(
        name: &str,
        pending: PendingLink,
        failure_context: &'static str,
        on_message: F,
    ) -> std::io::Result<Self>
    where
        F: FnMut(Received) -> ControlFlow<()> + Send + 'static,
    {
        let link = Arc::new(OnceLock::new());
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (link, stop) = (link.clone(), stop.clone());
            std::thread::Builder::new()
                .name(name.to_string())
                .spawn(move || {
                    if let Err(e) = receive_loop(pending, &link, &stop, on_message) {
                        // the error and its causes, each once
                        let mut line = format!("{failure_context}: {e}");
                        let mut cause = std::error::Error::source(&e);
                        while let Some(c) = cause {
                            line.push_str(&format!(": {c}"));
                            cause = c.source();
                        }
                        tracing::warn!("{line}");
                    }
                })?
        };
        Ok(Self {
            link,
            stop,
            thread: Some(thread),
            inline: None,
        })
    }

    /// A receiver without a thread: `pending` must be ready (UDP or serial: a `tcpin:`
    /// server waits for its peer, which only a thread can); it is made non-blocking, and
    /// [`LinkReceiver::pump`] hands what arrived to `on_message`.
    pub fn inline<F>(pending: PendingLink, on_message: F) -> Result<Self, LinkError>
    where
        F: FnMut(Received) -> ControlFlow<()> + Send + 'static,
    {
        let PendingLink::Ready(link) = pending else {
            return Err(LinkError::InlineNeedsDatagrams);
        };
        link.set_nonblocking()?;
        let slot = OnceLock::new();
        let _ = slot.set(*link);
        Ok(Self {
            link: Arc::new(slot),
            stop: Arc::new(AtomicBool::new(false)),
            thread: None,
            inline: Some(Box::new(on_message)),
        })
    }

    /// Inline: hand every message that has arrived to the handler, without waiting;
    /// returns how many. A receiver with a thread does nothing here (0).
    pub fn pump(&mut self) -> usize {
        let (Some(link), Some(handler)) = (self.link.get(), self.inline.as_mut()) else {
            return 0;
        };
        let mut handed = 0;
        loop {
            match link.recv() {
                Ok(Some(received)) => {
                    handed += 1;
                    if handler(received).is_break() {
                        self.inline = None;
                        return handed;
                    }
                }
                // a frame that did not decode: read on
                Err(LinkError::Decode) => {}
                // nothing more now (or a failing transport: the next turn tries again)
                Ok(None) | Err(_) => return handed,
            }
        }
    }

    /// The established link (to send on); `None` until the receive thread established it
    /// (a `tcpin:` server before its peer connected) or when it could not.
    pub fn link(&self) -> Option<&MavLink> {
        self.link.get()
    }

    /// Stop the receive thread and wait for it (at most about one [`LINK_POLL`]); the link
    /// stays usable for sending. Calling it again does nothing.
    pub fn stop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.thread.take() {
            let _ = h.join();
        }
    }
}

impl Drop for LinkReceiver {
    fn drop(&mut self) {
        self.stop();
    }
}

/// Establish `pending` into `slot`, then receive until `stop` or a `Break` from
/// `on_message`. Errs only when the link could not be established.
fn receive_loop<F>(
    pending: PendingLink,
    slot: &OnceLock<MavLink>,
    stop: &AtomicBool,
    mut on_message: F,
) -> Result<(), LinkError>
where
    F: FnMut(Received) -> ControlFlow<()>,
{
    let Some(link) = pending.establish(stop)? else {
        return Ok(());
    };
    let _ = slot.set(link);
    let Some(link) = slot.get() else {
        return Ok(());
    };
    while !stop.load(Ordering::Relaxed) {
        match link.recv() {
            Ok(Some(received)) => {
                if on_message(received).is_break() {
                    return Ok(());
                }
            }
            Ok(None) | Err(LinkError::Decode) => {}
            // closed or failing transport: back off without spinning
            Err(_) => std::thread::sleep(LINK_POLL),
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::{
        HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType,
    };
    use crate::link::{open_link, prepare_link};
    use crate::{MavHeader, MavlinkVersion};
    use mavlink::Message;
    use std::sync::mpsc::sync_channel;

    fn heartbeat(custom_mode: u32) -> MavMessage {
        MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode,
            mavtype: MavType::MAV_TYPE_QUADROTOR,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        })
    }

    /// Inline (simulated time): no thread; what a peer sent over the loopback is handed over
    /// by the next pump, in order, and a pump with nothing there returns at once; a `tcpin:`
    /// server is refused.
    #[test]
    fn an_inline_receiver_hands_over_what_arrived_when_pumped() {
        let server = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let addr = server.local_addr().unwrap();
        drop(server);
        let pending = prepare_link(&format!("udpin:{addr}"), LINK_POLL).unwrap();
        let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let sink = seen.clone();
        let mut receiver = LinkReceiver::inline(pending, move |r| {
            if let MavMessage::HEARTBEAT(hb) = r.message {
                sink.lock().unwrap().push(hb.custom_mode);
            }
            ControlFlow::Continue(())
        })
        .unwrap();
        assert_eq!(receiver.pump(), 0);
        let peer = open_link(&format!("udpout:{addr}"), LINK_POLL).unwrap();
        let header = MavHeader {
            system_id: 42,
            component_id: 1,
            sequence: 0,
        };
        for mode in 1..=3 {
            peer.send(&header, &heartbeat(mode)).unwrap();
        }
        assert_eq!(receiver.pump(), 3);
        assert_eq!(*seen.lock().unwrap(), vec![1, 2, 3]);
        // it answers the peer it heard
        let link = receiver.link().expect("an inline link is ready at once");
        link.send(&header, &heartbeat(9)).unwrap();
        let back = (0..200).find_map(|_| peer.recv().unwrap());
        assert!(
            matches!(back.map(|r| r.message), Some(MavMessage::HEARTBEAT(hb)) if hb.custom_mode == 9)
        );
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let tcp = listener.local_addr().unwrap();
        drop(listener);
        let pending = prepare_link(&format!("tcpin:{tcp}"), LINK_POLL).unwrap();
        assert!(matches!(
            LinkReceiver::inline(pending, |_| ControlFlow::Continue(())),
            Err(LinkError::InlineNeedsDatagrams)
        ));
    }

    /// A `tcpin:` server: the thread accepts the peer, delivers what it sends in order with
    /// its header and framing (MAVLink 2, then MAVLink 1 from a peer switched to it), the
    /// link then sends back in MAVLink 1, and a `Break` ends the thread.
    #[test]
    fn a_tcp_server_accepts_its_peer_and_hands_over_every_message() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        drop(listener);
        let pending = prepare_link(&format!("tcpin:{addr}"), LINK_POLL).unwrap();
        let (tx, rx) = sync_channel(16);
        let mut receiver = LinkReceiver::spawn("test-rx", pending, "test link", move |r| {
            let done = matches!(&r.message, MavMessage::HEARTBEAT(hb) if hb.custom_mode == 3);
            tx.send(r).unwrap();
            if done {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
        let peer = open_link(&format!("tcpout:{addr}"), LINK_POLL).unwrap();
        let header = MavHeader {
            system_id: 42,
            component_id: 1,
            sequence: 0,
        };
        for mode in 1..=3 {
            if mode == 3 {
                peer.set_send_version(MavlinkVersion::V1);
            }
            peer.send(&header, &heartbeat(mode)).unwrap();
        }
        for mode in 1..=3 {
            let r = rx.recv().unwrap();
            assert_eq!(r.header.system_id, 42);
            assert!(matches!(r.message, MavMessage::HEARTBEAT(hb) if hb.custom_mode == mode));
            let framing = if mode == 3 {
                MavlinkVersion::V1
            } else {
                MavlinkVersion::V2
            };
            assert_eq!(r.version, Some(framing), "heartbeat {mode}");
        }
        // the thread ended on the Break; the established link still sends, as MAVLink 1
        receiver.stop();
        let link = receiver.link().expect("established");
        link.set_send_version(MavlinkVersion::V1);
        assert!(link.send(&header, &heartbeat(9)).unwrap() > 0);
        // (a bound on the polls, not on time: a lost message fails instead of hanging)
        let back = (0..200).find_map(|_| peer.recv().unwrap());
        assert!(
            matches!(&back, Some(r) if r.version == Some(MavlinkVersion::V1)
                && matches!(&r.message, MavMessage::HEARTBEAT(hb) if hb.custom_mode == 9)),
            "{back:?}"
        );
        // a message with no MAVLink 1 encoding is refused, not mangled
        let long_id = MavMessage::default_message_from_id(385).expect("TUNNEL exists");
        assert!(matches!(
            link.send(&header, &long_id),
            Err(LinkError::NotInMavlink1 { message_id: 385 })
        ));
    }

    #[test]
    fn a_receiver_stops_while_its_server_still_waits_for_a_peer() {
        let pending = prepare_link("tcpin:127.0.0.1:0", LINK_POLL).unwrap();
        let mut receiver = LinkReceiver::spawn("test-rx", pending, "test link", |_| {
            ControlFlow::Continue(())
        })
        .unwrap();
        receiver.stop();
        assert!(receiver.link().is_none());
    }

    /// A signed link over TCP: frames signed with the key pass; unsigned ones (in either
    /// MAVLink version) and ones signed with another key are refused and counted; what it
    /// sends is signed (a peer with the key accepts it) and never MAVLink 1.
    #[test]
    fn a_signed_link_accepts_only_frames_signed_with_its_key() {
        use crate::signing::LinkSigning;
        let key = LinkSigning::from_text("the secret", 1).unwrap();
        let other = LinkSigning::from_text("another secret", 2).unwrap();
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        drop(listener);
        let pending = prepare_link(&format!("tcpin:{addr}"), LINK_POLL)
            .unwrap()
            .with_signing(Some(key));
        let (tx, rx) = sync_channel(16);
        let mut receiver = LinkReceiver::spawn("test-rx", pending, "test link", move |r| {
            let done = matches!(&r.message, MavMessage::HEARTBEAT(hb) if hb.custom_mode == 9);
            tx.send(r).unwrap();
            if done {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
        let mut peer = open_link(&format!("tcpout:{addr}"), LINK_POLL).unwrap();
        let header = MavHeader {
            system_id: 42,
            component_id: 1,
            sequence: 0,
        };
        // unsigned MAVLink 2, unsigned MAVLink 1, then another key: all refused
        peer.send(&header, &heartbeat(1)).unwrap();
        peer.set_send_version(MavlinkVersion::V1);
        peer.send(&header, &heartbeat(2)).unwrap();
        peer.set_send_version(MavlinkVersion::V2);
        peer.set_signing(other);
        peer.send(&header, &heartbeat(3)).unwrap();
        peer.set_signing(key);
        peer.send(&header, &heartbeat(9)).unwrap();
        let r = rx.recv().unwrap();
        assert!(
            matches!(&r.message, MavMessage::HEARTBEAT(hb) if hb.custom_mode == 9),
            "only the signed heartbeat arrives: {r:?}"
        );
        receiver.stop();
        let link = receiver.link().expect("established");
        assert_eq!(link.signing_refused(), (2, 1));
        assert!(link.send(&header, &heartbeat(5)).unwrap() > 0);
        let back = (0..200).find_map(|_| peer.recv().unwrap());
        assert!(
            matches!(&back, Some(r) if matches!(&r.message, MavMessage::HEARTBEAT(hb) if hb.custom_mode == 5)),
            "a peer with the key accepts what the link signs: {back:?}"
        );
        link.set_send_version(MavlinkVersion::V1);
        assert!(matches!(
            link.send(&header, &heartbeat(6)),
            Err(LinkError::SigningNeedsMavlink2)
        ));
    }
}
