//! CAN frames over python-can's `udp_multicast` wire format: each frame one UDP datagram to a
//! multicast group, holding a msgpack map of python-can's ``Message`` fields
//! (``can/interfaces/udp_multicast/utils.py``: timestamp, arbitration_id, is_extended_id,
//! is_remote_frame, is_error_frame, channel, dlc, data, is_fd, bitrate_switch,
//! error_state_indicator). Only the subset of msgpack those fields use is written and read.
//!
//! Every member of the group hears every datagram, its own too: frames this bus sent carry its
//! tag in the ``channel`` field and are dropped on receipt (as ecam's ``ecam_udp`` does).

use std::net::{Ipv4Addr, SocketAddrV4, UdpSocket};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use socket2::{Domain, Protocol, Socket, Type};

pub struct UdpCan {
    socket: UdpSocket,
    group: SocketAddrV4,
    tag: String,
}

impl UdpCan {
    pub fn open(group: &str, port: u16) -> Result<Self, String> {
        let group_ip: Ipv4Addr = group.parse().map_err(|e| format!("group {group}: {e}"))?;
        let err = |what: &str, e: std::io::Error| format!("udp multicast {group}:{port}: {what}: {e}");
        let socket = Socket::new(Domain::IPV4, Type::DGRAM, Some(Protocol::UDP)).map_err(|e| err("socket", e))?;
        // Several programs on one host share the group's port, as python-can's buses do.
        socket.set_reuse_address(true).map_err(|e| err("SO_REUSEADDR", e))?;
        socket.set_reuse_port(true).map_err(|e| err("SO_REUSEPORT", e))?;
        socket.bind(&SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, port).into()).map_err(|e| err("bind", e))?;
        socket.join_multicast_v4(&group_ip, &Ipv4Addr::UNSPECIFIED).map_err(|e| err("join", e))?;
        socket.set_multicast_ttl_v4(1).map_err(|e| err("TTL", e))?;
        // Non-blocking, polled with short sleeps: SO_RCVTIMEO counts in scheduler ticks (4 ms
        // at 250 Hz), too coarse for a 2 ms SYNC.
        socket.set_nonblocking(true).map_err(|e| err("non-blocking", e))?;
        Ok(Self {
            socket: socket.into(),
            group: SocketAddrV4::new(group_ip, port),
            tag: format!("canopen-rs-master:{}", std::process::id()),
        })
    }

    pub fn send(&self, cob: u16, data: &[u8]) -> Result<(), String> {
        let timestamp = SystemTime::now().duration_since(UNIX_EPOCH).map(|d| d.as_secs_f64()).unwrap_or(0.0);
        let mut out = Vec::with_capacity(160);
        out.push(0x8B); // fixmap, 11 entries
        key(&mut out, "timestamp");
        out.push(0xCB);
        out.extend_from_slice(&timestamp.to_bits().to_be_bytes());
        key(&mut out, "arbitration_id");
        out.push(0xCD);
        out.extend_from_slice(&cob.to_be_bytes());
        for flag in ["is_extended_id", "is_remote_frame", "is_error_frame"] {
            key(&mut out, flag);
            out.push(0xC2);
        }
        key(&mut out, "channel");
        out.push(0xD9);
        out.push(self.tag.len() as u8);
        out.extend_from_slice(self.tag.as_bytes());
        key(&mut out, "dlc");
        out.push(data.len() as u8);
        key(&mut out, "data");
        out.push(0xC4);
        out.push(data.len() as u8);
        out.extend_from_slice(data);
        for flag in ["is_fd", "bitrate_switch", "error_state_indicator"] {
            key(&mut out, flag);
            out.push(0xC2);
        }
        self.socket.send_to(&out, self.group).map_err(|e| format!("send: {e}"))?;
        Ok(())
    }

    /// The next frame of another node within `timeout`: (11-bit COB-ID, data).
    pub fn recv(&self, timeout: Duration) -> Result<Option<(u16, Vec<u8>)>, String> {
        let deadline = Instant::now() + timeout;
        let mut buffer = [0u8; 4096];
        loop {
            match self.socket.recv(&mut buffer) {
                Ok(n) => {
                    if let Some(frame) = decode(&buffer[..n]) {
                        let own = frame.channel.as_deref() == Some(self.tag.as_str());
                        if !(own || frame.extended || frame.remote || frame.error || frame.id > 0x7FF) {
                            return Ok(Some((frame.id as u16, frame.data)));
                        }
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    let now = Instant::now();
                    if now >= deadline {
                        return Ok(None);
                    }
                    std::thread::sleep((deadline - now).min(Duration::from_micros(100)));
                }
                Err(e) => return Err(format!("recv: {e}")),
            }
        }
    }
}

fn key(out: &mut Vec<u8>, name: &str) {
    out.push(0xA0 | name.len() as u8); // fixstr: every key is shorter than 32 bytes
    out.extend_from_slice(name.as_bytes());
}

#[derive(Default)]
struct Frame {
    id: u64,
    extended: bool,
    remote: bool,
    error: bool,
    channel: Option<String>,
    data: Vec<u8>,
}

enum Item {
    Nil,
    Bool(bool),
    Int(i128),
    Float,
    Str(String),
    Bin(Vec<u8>),
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.at.checked_add(n)?;
        let slice = self.bytes.get(self.at..end)?;
        self.at = end;
        Some(slice)
    }

    fn uint(&mut self, n: usize) -> Option<u64> {
        Some(self.take(n)?.iter().fold(0u64, |acc, b| acc << 8 | *b as u64))
    }

    fn item(&mut self) -> Option<Item> {
        let tag = *self.take(1)?.first()?;
        Some(match tag {
            0x00..=0x7F => Item::Int(tag as i128),
            0xE0..=0xFF => Item::Int(tag as i8 as i128),
            0xC0 => Item::Nil,
            0xC2 => Item::Bool(false),
            0xC3 => Item::Bool(true),
            0xCC => Item::Int(self.uint(1)? as i128),
            0xCD => Item::Int(self.uint(2)? as i128),
            0xCE => Item::Int(self.uint(4)? as i128),
            0xCF => Item::Int(self.uint(8)? as i128),
            0xD0 => Item::Int(self.uint(1)? as u8 as i8 as i128),
            0xD1 => Item::Int(self.uint(2)? as u16 as i16 as i128),
            0xD2 => Item::Int(self.uint(4)? as u32 as i32 as i128),
            0xD3 => Item::Int(self.uint(8)? as i64 as i128),
            0xCA => { self.take(4)?; Item::Float }
            0xCB => { self.take(8)?; Item::Float }
            0xA0..=0xBF => self.string((tag & 0x1F) as usize)?,
            0xD9 => { let n = self.uint(1)? as usize; self.string(n)? }
            0xDA => { let n = self.uint(2)? as usize; self.string(n)? }
            0xC4 => { let n = self.uint(1)? as usize; Item::Bin(self.take(n)?.to_vec()) }
            0xC5 => { let n = self.uint(2)? as usize; Item::Bin(self.take(n)?.to_vec()) }
            _ => return None, // nothing python-can writes for a frame
        })
    }

    fn string(&mut self, n: usize) -> Option<Item> {
        Some(Item::Str(String::from_utf8(self.take(n)?.to_vec()).ok()?))
    }
}

/// A python-can frame from one datagram; None for anything else.
fn decode(bytes: &[u8]) -> Option<Frame> {
    let mut reader = Reader { bytes, at: 0 };
    let tag = *reader.take(1)?.first()?;
    let entries = match tag {
        0x80..=0x8F => (tag & 0x0F) as usize,
        0xDE => reader.uint(2)? as usize,
        _ => return None,
    };
    let mut frame = Frame::default();
    for _ in 0..entries {
        let Item::Str(name) = reader.item()? else { return None };
        let value = reader.item()?;
        match (name.as_str(), value) {
            ("arbitration_id", Item::Int(v)) => frame.id = u64::try_from(v).ok()?,
            ("is_extended_id", Item::Bool(v)) => frame.extended = v,
            ("is_remote_frame", Item::Bool(v)) => frame.remote = v,
            ("is_error_frame", Item::Bool(v)) => frame.error = v,
            ("channel", Item::Str(v)) => frame.channel = Some(v),
            ("data", Item::Bin(v)) => frame.data = v,
            _ => {}
        }
    }
    (reader.at == bytes.len()).then_some(frame)
}
