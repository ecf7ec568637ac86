//! One MAVLink link on any supported URL: `udpin:`, `udpout:`, `udpbcast:`, `tcpin:`,
//! `tcpout:` (`udp:`/`tcp:` as aliases) and `serial:DEVICE:BAUD`. Receives time out after
//! the read timeout the link was prepared with, so a receive thread can stop cleanly;
//! sending works from any thread and does not allocate. The link receives MAVLink 1 and 2
//! frames of the [`crate::dialect`] and sends in the version set with
//! [`MavLink::set_send_version`] (MAVLink 2 until then), so it talks to autopilots and tools
//! that speak only MAVLink 1. On UDP and TCP the frames are found by our own scanner
//! ([`crate::transport`]) so that frames failing their CRC are counted
//! ([`MavLink::crc_failures`]); a serial port is the `mavlink` crate's connection.

use crate::MavHeader;
use crate::dialect::MavMessage;
use crate::signing::{LinkSigner, LinkSigning, SignatureVerdict};
use crate::transport::{Scanned, TcpTransport, UdpTransport};
use mavlink::error::{MessageReadError, MessageWriteError};
use mavlink::{
    Connectable, MAVLinkMessageRaw, MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, MavConnection,
    MavlinkVersion, Message, SerialConfig,
};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::time::Duration;

/// How long a receive call waits before giving the receive loop a chance to stop.
pub const LINK_POLL: Duration = Duration::from_millis(50);

/// The `mavlink` crate's connection (serial ports).
type Connection = mavlink::Connection<MavMessage>;

/// The bytes under a [`MavLink`].
enum Transport {
    /// A serial port, polled through the crate's connection.
    Serial(Box<Connection>),
    /// A UDP socket and our frame scanner.
    Udp(UdpTransport),
    /// A TCP stream and our frame scanner.
    Tcp(TcpTransport),
}

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
    /// Bytes arrived that do not decode as a common-dialect MAVLink 1 or 2 message.
    #[error("undecodable MAVLink data")]
    Decode,
    /// The link signs, and MAVLink 1 has no signature.
    #[error("a signed link sends MAVLink 2 only")]
    SigningNeedsMavlink2,
    /// A link received inline (on simulated time) must be ready at once: UDP or serial.
    #[error(
        "a link received without a thread (on simulated time) must be UDP or serial; a TCP link is not"
    )]
    InlineNeedsDatagrams,
    /// The message has no MAVLink 1 encoding (its id is above 255) and the link sends
    /// MAVLink 1.
    #[error("message {message_id} cannot be sent as MAVLink 1 (its id is above 255)")]
    NotInMavlink1 {
        /// The message id.
        message_id: u32,
    },
}

/// One message as it arrived.
#[derive(Debug, Clone, PartialEq)]
pub struct Received {
    /// Its sender and sequence number.
    pub header: MavHeader,
    /// The message.
    pub message: MavMessage,
    /// The framing it arrived in; `None` on links that do not report it (serial).
    pub version: Option<MavlinkVersion>,
}

/// An open MAVLink link: send from any thread, receive with a timeout.
pub struct MavLink {
    transport: Transport,
    /// Frame-shaped bytes whose CRC did not check (UDP and TCP).
    crc_failures: AtomicU64,
    /// 1 or 2: the framing [`MavLink::send`] writes.
    send_version: AtomicU8,
    /// The next outgoing sequence number.
    sequence: AtomicU8,
    /// MAVLink 2 signing, when on.
    signer: Option<LinkSigner>,
}

impl core::fmt::Debug for MavLink {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("MavLink").finish_non_exhaustive()
    }
}

impl MavLink {
    /// A link over `transport` that receives either MAVLink version and sends MAVLink 2.
    fn new(mut transport: Transport) -> Self {
        if let Transport::Serial(conn) = &mut transport {
            conn.set_allow_recv_any_version(true);
        }
        Self {
            transport,
            crc_failures: AtomicU64::new(0),
            send_version: AtomicU8::new(2),
            sequence: AtomicU8::new(0),
            signer: None,
        }
    }

    /// Sign everything sent from now on, and refuse every received frame that is not
    /// signed with `signing`'s key (counted: [`MavLink::signing_refused`]).
    /// On a serial link the `mavlink` crate checks the signatures itself: refusals are
    /// enforced there but not counted.
    pub fn set_signing(&mut self, signing: LinkSigning) {
        if let Transport::Serial(conn) = &mut self.transport {
            conn.setup_signing(Some(mavlink::SigningConfig::new(
                signing.key,
                signing.link_id,
                true,
                false,
            )));
        }
        self.signer = Some(LinkSigner::new(signing));
    }

    /// Frames received whose CRC did not check, dropped (0 on a serial link, where the
    /// `mavlink` crate drops them uncounted). A run of damaged bytes counts once.
    pub fn crc_failures(&self) -> u64 {
        self.crc_failures.load(Ordering::Relaxed)
    }

    /// Whether the link signs and checks signatures.
    pub fn is_signed(&self) -> bool {
        self.signer.is_some()
    }

    /// Received frames refused by signing so far: `(unsigned, badly signed)`.
    pub fn signing_refused(&self) -> (u64, u64) {
        self.signer.as_ref().map_or((0, 0), LinkSigner::refused)
    }

    /// Send in `version` from now on (MAVLink 1 for a peer that speaks only MAVLink 1).
    pub fn set_send_version(&self, version: MavlinkVersion) {
        let v = match version {
            MavlinkVersion::V1 => 1,
            MavlinkVersion::V2 => 2,
        };
        self.send_version.store(v, Ordering::Relaxed);
    }

    /// The version [`MavLink::send`] writes.
    pub fn send_version(&self) -> MavlinkVersion {
        match self.send_version.load(Ordering::Relaxed) {
            1 => MavlinkVersion::V1,
            _ => MavlinkVersion::V2,
        }
    }

    /// Send `msg` from the sender in `header` (the sequence number is the link's own) in the
    /// link's send version. `Ok(0)` means there is no peer yet (a `udpin:` link before
    /// anything arrived). Does not allocate: the frame is built on the stack.
    pub fn send(&self, header: &MavHeader, msg: &MavMessage) -> Result<usize, LinkError> {
        let header = MavHeader {
            sequence: self.sequence.fetch_add(1, Ordering::Relaxed),
            ..*header
        };
        let raw = match self.send_version() {
            MavlinkVersion::V1 if self.signer.is_some() => {
                return Err(LinkError::SigningNeedsMavlink2);
            }
            MavlinkVersion::V1 => {
                let message_id = msg.message_id();
                if message_id > u32::from(u8::MAX) || header.system_id > u32::from(u8::MAX) {
                    return Err(LinkError::NotInMavlink1 { message_id });
                }
                let mut raw = MAVLinkV1MessageRaw::new();
                raw.serialize_message(header, msg);
                MAVLinkMessageRaw::V1(raw)
            }
            MavlinkVersion::V2 => {
                let mut raw = MAVLinkV2MessageRaw::new();
                match &self.signer {
                    Some(signer) => {
                        raw.serialize_message_for_signing(header, msg);
                        signer.sign(&mut raw);
                    }
                    None => raw.serialize_message(header, msg),
                }
                MAVLinkMessageRaw::V2(raw)
            }
        };
        let bytes = match &raw {
            MAVLinkMessageRaw::V1(r) => r.raw_bytes(),
            MAVLinkMessageRaw::V2(r) => r.raw_bytes(),
        };
        match &self.transport {
            Transport::Serial(conn) => conn.send_raw(&raw).map_err(|e| match e {
                MessageWriteError::Io(io) => LinkError::Send(io.to_string()),
                other => LinkError::Send(format!("{other:?}")),
            }),
            Transport::Udp(t) => t.send(bytes).map_err(|e| LinkError::Send(e.to_string())),
            Transport::Tcp(t) => t.send(bytes).map_err(|e| LinkError::Send(e.to_string())),
        }
    }

    /// A raw frame that passed its CRC, checked against the signing and decoded.
    fn accept(&self, raw: MAVLinkMessageRaw) -> Result<Option<Received>, MessageReadError> {
        if let Some(signer) = &self.signer
            && signer.check(&raw) != SignatureVerdict::Valid
        {
            // refused and counted: nothing for the caller this poll
            return Ok(None);
        }
        let message = MavMessage::parse(raw.version(), raw.message_id(), raw.payload())?;
        Ok(Some(Received {
            header: MavHeader {
                system_id: raw.system_id(),
                component_id: raw.component_id(),
                sequence: raw.sequence(),
            },
            message,
            version: Some(raw.version()),
        }))
    }

    /// One scanned step of a UDP or TCP link as a receive result.
    fn scanned(
        &self,
        step: std::io::Result<Scanned>,
    ) -> Result<Option<Received>, MessageReadError> {
        match step? {
            Scanned::Frame(raw) => self.accept(raw),
            Scanned::CrcFailure => {
                self.crc_failures.fetch_add(1, Ordering::Relaxed);
                Ok(None)
            }
            Scanned::NeedMore => Ok(None),
        }
    }

    /// Make receives return at once when nothing has arrived (`Ok(None)`) instead of
    /// waiting for the read timeout: UDP (sends stay as they are: a datagram never waits
    /// for its peer) and serial (already polled); a TCP link is refused.
    pub fn set_nonblocking(&self) -> Result<(), LinkError> {
        match &self.transport {
            Transport::Serial(_) => Ok(()),
            Transport::Udp(t) => t.set_nonblocking().map_err(LinkError::Receive),
            Transport::Tcp(_) => Err(LinkError::InlineNeedsDatagrams),
        }
    }

    /// Receive one message of either MAVLink version; `Ok(None)` when nothing arrived
    /// within the link's poll timeout.
    pub fn recv(&self) -> Result<Option<Received>, LinkError> {
        let r = match &self.transport {
            // a serial port is polled (its blocking read retries timeouts for ever); the
            // crate reports no framing version there
            Transport::Serial(conn) => conn.try_recv().map(|(header, message)| {
                Some(Received {
                    header,
                    message,
                    version: None,
                })
            }),
            Transport::Udp(t) => self.scanned(t.recv()),
            Transport::Tcp(t) => self.scanned(t.recv()),
        };
        match r {
            Ok(m) => Ok(m),
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
    /// Ready to use (boxed: a link is far larger than a listener).
    Ready(Box<MavLink>),
    /// A bound `tcpin:` listener; [`PendingLink::establish`] accepts the peer.
    Listening {
        /// The bound listener.
        listener: TcpListener,
        /// Read timeout of the accepted stream.
        timeout: Duration,
        /// Signing for the accepted link.
        signing: Option<LinkSigning>,
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
    let transport = TcpTransport::new(stream).map_err(open_err(url))?;
    Ok(MavLink::new(Transport::Tcp(transport)))
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
    let udp = |opened: std::io::Result<UdpTransport>| -> Result<PendingLink, LinkError> {
        let transport = opened.map_err(open_err(url))?;
        transport.set_read_timeout(timeout).map_err(open_err(url))?;
        Ok(PendingLink::Ready(Box::new(MavLink::new(Transport::Udp(
            transport,
        )))))
    };
    match proto {
        "udpin" | "udp" => udp(UdpTransport::server(addr)),
        "udpout" => udp(UdpTransport::client(addr, false)),
        "udpbcast" => udp(UdpTransport::client(addr, true)),
        "tcpout" | "tcp" => {
            let stream = TcpStream::connect(addr).map_err(open_err(url))?;
            Ok(PendingLink::Ready(Box::new(tcp_link(
                stream, timeout, url,
            )?)))
        }
        "tcpin" => {
            let listener = TcpListener::bind(addr).map_err(open_err(url))?;
            Ok(PendingLink::Listening {
                listener,
                timeout,
                signing: None,
            })
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
            Ok(PendingLink::Ready(Box::new(MavLink::new(
                Transport::Serial(Box::new(conn)),
            ))))
        }
        _ => Err(LinkError::Address(url.to_string())),
    }
}

impl PendingLink {
    /// Sign and check signatures on the link with `signing` (nothing changes for `None`).
    pub fn with_signing(self, signing: Option<LinkSigning>) -> Self {
        let Some(s) = signing else {
            return self;
        };
        match self {
            PendingLink::Ready(mut link) => {
                link.set_signing(s);
                PendingLink::Ready(link)
            }
            PendingLink::Listening {
                listener, timeout, ..
            } => PendingLink::Listening {
                listener,
                timeout,
                signing: Some(s),
            },
        }
    }

    /// The open link; for a `tcpin:` server, wait for the peer to connect. Returns
    /// `Ok(None)` when `stop` became true while waiting.
    pub fn establish(self, stop: &AtomicBool) -> Result<Option<MavLink>, LinkError> {
        match self {
            PendingLink::Ready(link) => Ok(Some(*link)),
            PendingLink::Listening {
                listener,
                timeout,
                signing,
            } => {
                let url = listener
                    .local_addr()
                    .map(|a| format!("tcpin:{a}"))
                    .unwrap_or_else(|_| "tcpin".to_string());
                listener.set_nonblocking(true).map_err(open_err(&url))?;
                while !stop.load(Ordering::Relaxed) {
                    match listener.accept() {
                        Ok((stream, _)) => {
                            stream.set_nonblocking(false).map_err(open_err(&url))?;
                            let mut link = tcp_link(stream, timeout, &url)?;
                            if let Some(s) = signing {
                                link.set_signing(s);
                            }
                            return Ok(Some(link));
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
