//! The byte side of a UDP or TCP link: sockets, and the framing that finds MAVLink 1 and 2
//! frames in what arrives and checks their CRC.
//!
//! The `mavlink` crate's connections skip a frame whose CRC does not check without a word,
//! so a link that hears only corrupted frames (a wrong baud rate behind a radio bridge, a
//! dialect whose CRC seeds differ, line noise) would look exactly like a silent one. Here the
//! frames are cut out of the bytes by [`FrameScanner`], which counts CRC failures; the
//! frames themselves, their CRC and their messages are still the crate's types and
//! functions ([`calculate_crc`], [`MAVLinkV1MessageRaw`], [`MAVLinkV2MessageRaw`],
//! [`Message::parse`]). Serial ports stay on the crate's connection (there is no hook there;
//! their CRC failures are not counted).
//!
//! The UDP modes are the crate's: `udpin` binds the address and answers whoever sent last,
//! `udpout` and `udpbcast` bind an ephemeral port and send to the address (`udpbcast` with
//! broadcast on). Nothing here allocates after the link is opened.

use crate::dialect::MavMessage;
use mavlink::{
    MAVLinkMessageRaw, MAVLinkV1MessageRaw, MAVLinkV2MessageRaw, Message, calculate_crc,
};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::sync::Mutex;

/// Start-of-frame byte of MAVLink 1.
const STX_V1: u8 = 0xFE;
/// Start-of-frame byte of MAVLink 2.
const STX_V2: u8 = 0xFD;
/// MAVLink 2 incompatibility flag: the frame is signed.
const IFLAG_SIGNED: u8 = 0x01;
/// MAVLink 2 signature length.
const SIGNATURE_LEN: usize = 13;
/// Bytes the scanner holds: more than a UDP datagram of frames and any frame (280 bytes).
const SCAN_BUFFER: usize = 65_536;

/// One step of [`FrameScanner::next_frame`].
// the frame is moved out by value: boxing it would allocate on every receive
#[allow(clippy::large_enum_variant)]
pub(crate) enum Scanned {
    /// A frame whose CRC checks.
    Frame(MAVLinkMessageRaw),
    /// A frame-shaped run of bytes whose CRC does not check (counted once per run: the bytes
    /// after it are searched again, and what they hold before the next good frame is part of
    /// the same damage).
    CrcFailure,
    /// No whole frame in the buffer: read more.
    NeedMore,
}

/// Finds frames in a byte stream (TCP) or in one datagram at a time (UDP).
pub(crate) struct FrameScanner {
    buf: Box<[u8]>,
    start: usize,
    end: usize,
    /// A CRC failure was reported since the last good frame (the run counts once).
    in_damage: bool,
}

impl core::fmt::Debug for FrameScanner {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("FrameScanner")
            .field("buffered", &(self.end - self.start))
            .finish()
    }
}

impl FrameScanner {
    pub(crate) fn new() -> Self {
        Self {
            buf: vec![0; SCAN_BUFFER].into_boxed_slice(),
            start: 0,
            end: 0,
            in_damage: false,
        }
    }

    /// Forget what is buffered (a new datagram: frames never span two).
    pub(crate) fn clear(&mut self) {
        self.start = 0;
        self.end = 0;
        self.in_damage = false;
    }

    /// Room to read into, after moving what is buffered to the front.
    pub(crate) fn spare(&mut self) -> &mut [u8] {
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        if self.end == self.buf.len() {
            // a full buffer without a frame in it is noise: keep reading
            self.end = 0;
        }
        &mut self.buf[self.end..]
    }

    /// `n` bytes were read into [`FrameScanner::spare`].
    pub(crate) fn commit(&mut self, n: usize) {
        self.end = (self.end + n).min(self.buf.len());
    }

    /// The next frame in the buffered bytes, a CRC failure, or the need for more bytes.
    pub(crate) fn next_frame(&mut self) -> Scanned {
        loop {
            let Some(offset) = self.buf[self.start..self.end]
                .iter()
                .position(|&b| b == STX_V1 || b == STX_V2)
            else {
                self.start = self.end;
                return Scanned::NeedMore;
            };
            self.start += offset;
            let bytes = &self.buf[self.start..self.end];
            let v2 = bytes[0] == STX_V2;
            // the length (and for MAVLink 2 the incompatibility flags) say how long it is
            if bytes.len() < 3 {
                return Scanned::NeedMore;
            }
            let payload_len = usize::from(bytes[1]);
            let (header_len, signature_len) = if v2 {
                if bytes[2] & !IFLAG_SIGNED != 0 {
                    // a flag we do not know: not a frame we can read
                    self.start += 1;
                    continue;
                }
                let signed = bytes[2] & IFLAG_SIGNED != 0;
                (10, if signed { SIGNATURE_LEN } else { 0 })
            } else {
                (6, 0)
            };
            let checksum_at = header_len + payload_len;
            let frame_len = checksum_at + 2 + signature_len;
            if bytes.len() < frame_len {
                return Scanned::NeedMore;
            }
            let message_id = if v2 {
                u32::from_le_bytes([bytes[7], bytes[8], bytes[9], 0])
            } else {
                u32::from(bytes[5])
            };
            let expected = u16::from_le_bytes([bytes[checksum_at], bytes[checksum_at + 1]]);
            let actual = calculate_crc(&bytes[1..checksum_at], MavMessage::extra_crc(message_id));
            if actual != expected {
                self.start += 1;
                if self.in_damage {
                    continue;
                }
                self.in_damage = true;
                return Scanned::CrcFailure;
            }
            let frame = &bytes[..frame_len];
            let raw = if v2 {
                let mut raw = MAVLinkV2MessageRaw::new();
                raw.as_mut_slice()[..frame_len].copy_from_slice(frame);
                MAVLinkMessageRaw::V2(raw)
            } else {
                let mut raw = MAVLinkV1MessageRaw::new();
                raw.as_mut_slice()[..frame_len].copy_from_slice(frame);
                MAVLinkMessageRaw::V1(raw)
            };
            self.start += frame_len;
            self.in_damage = false;
            return Scanned::Frame(raw);
        }
    }
}

/// Where a UDP link sends.
#[derive(Debug)]
pub(crate) struct UdpTransport {
    socket: UdpSocket,
    /// The destination: fixed (`udpout`, `udpbcast`) or the last sender (`udpin`).
    destination: Mutex<Option<SocketAddr>>,
    /// `udpin`: answer whoever sent last.
    answers_sender: bool,
    scanner: Mutex<FrameScanner>,
}

impl UdpTransport {
    /// `udpin`: bound to `address`, answering the last sender.
    pub(crate) fn server(address: &str) -> std::io::Result<Self> {
        Ok(Self::new(UdpSocket::bind(address)?, None, true))
    }

    /// `udpout` (or `udpbcast` with `broadcast`): an ephemeral port sending to `address`.
    pub(crate) fn client(address: &str, broadcast: bool) -> std::io::Result<Self> {
        let destination = std::net::ToSocketAddrs::to_socket_addrs(address)?
            .next()
            .ok_or_else(|| {
                std::io::Error::new(
                    std::io::ErrorKind::AddrNotAvailable,
                    "the address resolves to nothing",
                )
            })?;
        let socket = UdpSocket::bind("0.0.0.0:0")?;
        if broadcast {
            socket.set_broadcast(true)?;
        }
        Ok(Self::new(socket, Some(destination), false))
    }

    fn new(socket: UdpSocket, destination: Option<SocketAddr>, answers_sender: bool) -> Self {
        Self {
            socket,
            destination: Mutex::new(destination),
            answers_sender,
            scanner: Mutex::new(FrameScanner::new()),
        }
    }

    pub(crate) fn set_read_timeout(&self, t: std::time::Duration) -> std::io::Result<()> {
        self.socket.set_read_timeout(Some(t))
    }

    pub(crate) fn set_nonblocking(&self) -> std::io::Result<()> {
        self.socket.set_nonblocking(true)
    }

    /// Send one frame; `Ok(0)` when there is nobody to send to yet (`udpin` before anything
    /// arrived).
    pub(crate) fn send(&self, frame: &[u8]) -> std::io::Result<usize> {
        let to = *self
            .destination
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        match to {
            Some(to) => self.socket.send_to(frame, to),
            None => Ok(0),
        }
    }

    /// The next scanned step: from the datagram being read, else from a new one.
    pub(crate) fn recv(&self) -> std::io::Result<Scanned> {
        let mut scanner = self
            .scanner
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        match scanner.next_frame() {
            Scanned::NeedMore => {}
            step => return Ok(step),
        }
        scanner.clear();
        let (n, from) = self.socket.recv_from(scanner.spare())?;
        scanner.commit(n);
        if self.answers_sender {
            *self
                .destination
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(from);
        }
        Ok(scanner.next_frame())
    }
}

/// A TCP stream: frames may span reads.
#[derive(Debug)]
pub(crate) struct TcpTransport {
    writer: Mutex<TcpStream>,
    reader: Mutex<(TcpStream, FrameScanner)>,
}

impl TcpTransport {
    pub(crate) fn new(stream: TcpStream) -> std::io::Result<Self> {
        let reader = stream.try_clone()?;
        Ok(Self {
            writer: Mutex::new(stream),
            reader: Mutex::new((reader, FrameScanner::new())),
        })
    }

    pub(crate) fn send(&self, frame: &[u8]) -> std::io::Result<usize> {
        let mut w = self
            .writer
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        w.write_all(frame)?;
        Ok(frame.len())
    }

    /// The next scanned step, reading once when the buffer holds no whole frame; a closed
    /// stream is `UnexpectedEof`.
    pub(crate) fn recv(&self) -> std::io::Result<Scanned> {
        let mut guard = self
            .reader
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let (stream, scanner) = &mut *guard;
        match scanner.next_frame() {
            Scanned::NeedMore => {}
            step => return Ok(step),
        }
        let n = stream.read(scanner.spare())?;
        if n == 0 {
            return Err(std::io::ErrorKind::UnexpectedEof.into());
        }
        scanner.commit(n);
        Ok(scanner.next_frame())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dialect::HEARTBEAT_DATA;
    use mavlink::{MavHeader, MavlinkVersion};

    fn frame(version: MavlinkVersion, sequence: u8) -> Vec<u8> {
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence,
        };
        let msg = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        match version {
            MavlinkVersion::V1 => {
                let mut raw = MAVLinkV1MessageRaw::new();
                raw.serialize_message(header, &msg);
                raw.raw_bytes().to_vec()
            }
            MavlinkVersion::V2 => {
                let mut raw = MAVLinkV2MessageRaw::new();
                raw.serialize_message(header, &msg);
                raw.raw_bytes().to_vec()
            }
        }
    }

    fn feed(s: &mut FrameScanner, bytes: &[u8]) {
        s.spare()[..bytes.len()].copy_from_slice(bytes);
        s.commit(bytes.len());
    }

    /// Sequence numbers of the frames found, and the CRC failures, until more is needed.
    fn drain(s: &mut FrameScanner) -> (Vec<u8>, usize) {
        let (mut seqs, mut bad) = (Vec::new(), 0);
        loop {
            match s.next_frame() {
                Scanned::Frame(raw) => seqs.push(raw.sequence()),
                Scanned::CrcFailure => bad += 1,
                Scanned::NeedMore => return (seqs, bad),
            }
        }
    }

    #[test]
    fn finds_both_versions_among_noise_and_frames_split_across_reads() {
        let mut s = FrameScanner::new();
        let mut bytes = vec![0x00, 0x42];
        bytes.extend(frame(MavlinkVersion::V1, 1));
        bytes.extend([0x13]);
        bytes.extend(frame(MavlinkVersion::V2, 2));
        let (head, tail) = bytes.split_at(bytes.len() - 5);
        feed(&mut s, head);
        assert_eq!(drain(&mut s), (vec![1], 0));
        feed(&mut s, tail);
        assert_eq!(drain(&mut s), (vec![2], 0));
    }

    #[test]
    fn a_corrupted_frame_is_one_crc_failure_and_the_next_frame_still_decodes() {
        let mut s = FrameScanner::new();
        let mut bad = frame(MavlinkVersion::V2, 1);
        let n = bad.len();
        bad[n - 1] ^= 0xff;
        let mut bytes = bad.clone();
        bytes.extend(frame(MavlinkVersion::V2, 2));
        feed(&mut s, &bytes);
        assert_eq!(drain(&mut s), (vec![2], 1));
        // two damaged frames back to back, then a good one: the damage counts once
        let mut bytes = bad.clone();
        bytes.extend(&bad);
        bytes.extend(frame(MavlinkVersion::V1, 3));
        feed(&mut s, &bytes);
        assert_eq!(drain(&mut s), (vec![3], 1));
        // a new datagram starts a new count
        s.clear();
        feed(&mut s, &bad);
        assert_eq!(drain(&mut s), (vec![], 1));
    }
}
