//! One MAVLink link on any supported URL: `udpin:`, `udpout:`, `udpbcast:`, `tcpin:`,
//! `tcpout:` (`udp:`/`tcp:` as aliases) and `serial:DEVICE:BAUD`. Receives time out after
//! the read timeout the link was prepared with, so a receive thread can stop cleanly;
//! sending works from any thread and does not allocate. The link speaks MAVLink 2 in the
//! [`crate::dialect`].

use crate::MavHeader;
use crate::dialect::MavMessage;
use mavlink::error::{MessageReadError, MessageWriteError};
use mavlink::{Connectable, MavConnection, SerialConfig, TcpConfig, UdpConfig, UdpMode};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// How long a receive call waits before giving the receive loop a chance to stop.
pub const LINK_POLL: Duration = Duration::from_millis(50);

/// The connection under a [`MavLink`].
type Connection = mavlink::Connection<MavMessage>;

/// Why a MAVLink link operation failed.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The URL does not name a supported transport.
    #[error(
        "unsupported MAVLink address `{0}` (use udpin:HOST:PORT, udpout:HOST:PORT, udpbcast:HOST:PORT, \
         tcpin:HOST:PORT, tcpout:HOST:PORT or serial:DEVICE:BAUD)"
    )]
    Address(String),
    /// The transport could not be opened (bind, connect, device).
    #[error("cannot open MAVLink link `{url}`")]
    Open {
        /// The URL.
        url: String,
        /// The cause.
        source: std::io::Error,
    },
    /// Writing a message failed.
    #[error("MAVLink send failed: {0}")]
    Send(String),
    /// Reading failed with an I/O error other than a timeout.
    #[error("MAVLink receive failed: {0}")]
    Receive(std::io::Error),
    /// The peer closed the stream (TCP) or the device went away.
    #[error("the MAVLink peer closed the link")]
    Closed,
    /// Bytes arrived that do not decode as a common-dialect MAVLink 2 message.
    #[error("undecodable MAVLink data")]
    Decode,
}

/// An open MAVLink link: send from any thread, receive with a timeout.
pub struct MavLink {
    conn: Connection,
    poll_with_try_recv: bool,
}

impl core::fmt::Debug for MavLink {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("MavLink").finish_non_exhaustive()
    }
}

impl MavLink {
    /// Send `msg` with `header` (the sequence number is filled in). `Ok(0)` means there is
    /// no peer yet (a `udpin:` link before anything arrived). Does not allocate.
    pub fn send(&self, header: &MavHeader, msg: &MavMessage) -> Result<usize, LinkError> {
        self.conn.send(header, msg).map_err(|e| match e {
            MessageWriteError::Io(io) => LinkError::Send(io.to_string()),
            other => LinkError::Send(format!("{other:?}")),
        })
    }

    /// Receive one message; `Ok(None)` when nothing arrived within the link's poll timeout.
    pub fn recv(&self) -> Result<Option<(MavHeader, MavMessage)>, LinkError> {
        let r = if self.poll_with_try_recv {
            self.conn.try_recv()
        } else {
            self.conn.recv()
        };
        match r {
            Ok(m) => Ok(Some(m)),
            Err(MessageReadError::Io(e)) => match e.kind() {
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut => Ok(None),
                std::io::ErrorKind::UnexpectedEof
                | std::io::ErrorKind::ConnectionReset
                | std::io::ErrorKind::BrokenPipe
                | std::io::ErrorKind::NotConnected => Err(LinkError::Closed),
                _ => Err(LinkError::Receive(e)),
            },
            Err(MessageReadError::Parse(_)) => Err(LinkError::Decode),
        }
    }
}

/// A link that is open, or a TCP server still waiting for its peer.
#[derive(Debug)]
pub enum PendingLink {
    /// Ready to use.
    Ready(MavLink),
    /// A bound `tcpin:` listener; [`PendingLink::establish`] accepts the peer.
    Listening {
        /// The bound listener.
        listener: TcpListener,
        /// Read timeout of the accepted stream.
        timeout: Duration,
    },
}

fn open_err(url: &str) -> impl FnOnce(std::io::Error) -> LinkError + '_ {
    move |source| LinkError::Open {
        url: url.to_string(),
        source,
    }
}

fn tcp_link(stream: TcpStream, timeout: Duration, url: &str) -> Result<MavLink, LinkError> {
    stream.set_nodelay(true).map_err(open_err(url))?;
    stream
        .set_read_timeout(Some(timeout))
        .map_err(open_err(url))?;
    let conn = TcpConfig::from_stream(stream)
        .map_err(open_err(url))?
        .connect::<MavMessage>()
        .map_err(open_err(url))?;
    Ok(MavLink {
        conn,
        poll_with_try_recv: false,
    })
}

/// Parse `url` and open its transport (binding, connecting, opening the device), except
/// that a `tcpin:` server is only bound: its peer is accepted by [`PendingLink::establish`].
/// Receives on the link time out after `read_timeout` (never zero).
pub fn prepare_link(url: &str, read_timeout: Duration) -> Result<PendingLink, LinkError> {
    let timeout = read_timeout.max(Duration::from_millis(1));
    let (proto, addr) = url
        .split_once(':')
        .ok_or_else(|| LinkError::Address(url.to_string()))?;
    if addr.is_empty() {
        return Err(LinkError::Address(url.to_string()));
    }
    let udp = |mode| -> Result<PendingLink, LinkError> {
        let conn = UdpConfig::new(addr.to_string(), mode)
            .read_timeout(timeout)
            .connect::<MavMessage>()
            .map_err(open_err(url))?;
        Ok(PendingLink::Ready(MavLink {
            conn,
            poll_with_try_recv: false,
        }))
    };
    match proto {
        "udpin" | "udp" => udp(UdpMode::Udpin),
        "udpout" => udp(UdpMode::Udpout),
        "udpbcast" => udp(UdpMode::UdpBroadcast),
        "tcpout" | "tcp" => {
            let stream = TcpStream::connect(addr).map_err(open_err(url))?;
            Ok(PendingLink::Ready(tcp_link(stream, timeout, url)?))
        }
        "tcpin" => {
            let listener = TcpListener::bind(addr).map_err(open_err(url))?;
            Ok(PendingLink::Listening { listener, timeout })
        }
        "serial" => {
            let (port, baud) = addr
                .rsplit_once(':')
                .ok_or_else(|| LinkError::Address(url.to_string()))?;
            let baud: u32 = baud
                .parse()
                .map_err(|_| LinkError::Address(url.to_string()))?;
            let conn = SerialConfig::new(port.to_string(), baud)
                .timeout(timeout)
                .connect::<MavMessage>()
                .map_err(open_err(url))?;
            Ok(PendingLink::Ready(MavLink {
                conn,
                poll_with_try_recv: true,
            }))
        }
        _ => Err(LinkError::Address(url.to_string())),
    }
}

impl PendingLink {
    /// The open link; for a `tcpin:` server, wait for the peer to connect. Returns
    /// `Ok(None)` when `stop` became true while waiting.
    pub fn establish(self, stop: &AtomicBool) -> Result<Option<MavLink>, LinkError> {
        match self {
            PendingLink::Ready(link) => Ok(Some(link)),
            PendingLink::Listening { listener, timeout } => {
                let url = listener
                    .local_addr()
                    .map(|a| format!("tcpin:{a}"))
                    .unwrap_or_else(|_| "tcpin".to_string());
                listener.set_nonblocking(true).map_err(open_err(&url))?;
                while !stop.load(Ordering::Relaxed) {
                    match listener.accept() {
                        Ok((stream, _)) => {
                            stream.set_nonblocking(false).map_err(open_err(&url))?;
                            return tcp_link(stream, timeout, &url).map(Some);
                        }
                        Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                            std::thread::sleep(Duration::from_millis(20));
                        }
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                        Err(source) => return Err(LinkError::Open { url, source }),
                    }
                }
                Ok(None)
            }
        }
    }
}

/// Open `url` and return the link (blocks until the peer connects for `tcpin:`).
pub fn open_link(url: &str, read_timeout: Duration) -> Result<MavLink, LinkError> {
    let never = AtomicBool::new(false);
    prepare_link(url, read_timeout)?
        .establish(&never)?
        .ok_or_else(|| LinkError::Address(url.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_addresses_are_refused() {
        for url in ["", "udpin", "foo:1.2.3.4:5", "serial:/dev/null", "udpin:"] {
            assert!(
                matches!(
                    prepare_link(url, LINK_POLL),
                    Err(LinkError::Address(_)) | Err(LinkError::Open { .. })
                ),
                "{url}"
            );
        }
    }
}
