//! A CiA 402 master written with canopen-rs (an independent CANopen stack: its own SDO client,
//! NMT, PDO and EMCY codecs), driving the ecam virtual drive over python-can's udp_multicast
//! wire format (one msgpack map per frame, UDP multicast group 239.74.163.2 port 43113).
//!
//!     ecam-canopen-rs-master NODE_ID
//!
//! Prints one `step: ...` line per stage reached and `ok` at the end; exits 1 at the first
//! stage that fails. Run by tests/test_drive_interop.py inside a private network namespace
//! (loopback only), with `ecam drive --interface udp_multicast --node-id NODE_ID` already
//! started: it waits for the drive's heartbeat.
//!
//! canopen-rs is sans-I/O: it encodes and decodes the frames and runs the SDO client's state
//! machine; the transport (udp_can.rs), the SYNC timing and the CiA 402 sequence are here.

mod udp_can;

use std::process::ExitCode;
use std::time::{Duration, Instant};

use canopen_rs::emcy::EmergencyMessage;
use canopen_rs::nmt::{self, NmtCommand, NmtState};
use canopen_rs::pdo::{self, MappingEntry, PdoMapping};
use canopen_rs::sdo::{SdoClient, SdoEvent};
use canopen_rs::{Address, DataType, Entry, NodeId, ObjectDictionary, Value};

use udp_can::UdpCan;

const SYNC_PERIOD: Duration = Duration::from_millis(2);
const DEVICE_TYPE_SERVO: u32 = 0x0002_0192; // CiA 402 servo drive
const CSP: i8 = 8;
const EMCY_FOLLOWING_ERROR: u16 = 0x8611;
const EMCY_SYNC_LOST: u16 = 0x8100; // CiA 301: communication, generic

type Failure = String;

macro_rules! check {
    ($cond:expr, $($arg:tt)*) => {
        if !$cond {
            return Err(format!($($arg)*));
        }
    };
}

/// One stage reached, with the seconds since the first.
fn step(text: &str) {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    let elapsed = START.get_or_init(Instant::now).elapsed().as_secs_f64();
    println!("step: {text} ({elapsed:.2} s)");
}

/// The master's side of the process data: the objects its PDOs carry, in a canopen-rs
/// object dictionary, packed and unpacked by canopen-rs.
struct ProcessImage {
    od: ObjectDictionary<8>,
    rpdo1: PdoMapping<8>,
    rpdo2: PdoMapping<8>,
    tpdo1: PdoMapping<8>,
}

type Items = &'static [(Address, u8)];
const RPDO1: Items = &[(CONTROLWORD, 16), (MODES_OF_OPERATION, 8)]; // event-driven
const RPDO2: Items = &[(TARGET_POSITION, 32), (VELOCITY_OFFSET, 32)]; // synchronous
const TPDO1: Items = &[(STATUSWORD, 16), (POSITION_ACTUAL, 32)]; // synchronous

fn mapping(items: Items) -> Result<PdoMapping<8>, Failure> {
    let mut m = PdoMapping::new();
    for (a, bits) in items {
        m.push(MappingEntry::new(a.index, a.subindex, *bits)).map_err(|e| format!("{e:?}"))?;
    }
    Ok(m)
}

const CONTROLWORD: Address = Address::new(0x6040, 0);
const MODES_OF_OPERATION: Address = Address::new(0x6060, 0);
const TARGET_POSITION: Address = Address::new(0x607A, 0);
const VELOCITY_OFFSET: Address = Address::new(0x60B1, 0);
const STATUSWORD: Address = Address::new(0x6041, 0);
const POSITION_ACTUAL: Address = Address::new(0x6064, 0);

impl ProcessImage {
    fn new() -> Result<Self, Failure> {
        let mut od = ObjectDictionary::new();
        let entries = [
            (CONTROLWORD, Value::Unsigned16(0)),
            (MODES_OF_OPERATION, Value::Integer8(CSP)),
            (TARGET_POSITION, Value::Integer32(0)),
            (VELOCITY_OFFSET, Value::Integer32(0)),
            (STATUSWORD, Value::Unsigned16(0)),
            (POSITION_ACTUAL, Value::Integer32(0)),
        ];
        for (address, value) in entries {
            od.insert(address, Entry::rw(value)).map_err(|e| format!("{e:?}"))?;
        }
        Ok(Self { rpdo1: mapping(RPDO1)?, rpdo2: mapping(RPDO2)?, tpdo1: mapping(TPDO1)?, od })
    }

    fn pack(&mut self, which: u8, values: &[(Address, Value)]) -> Result<Vec<u8>, Failure> {
        for (a, v) in values {
            self.od.write(*a, *v).map_err(|e| format!("{e:?}"))?;
        }
        let mapping = if which == 1 { &self.rpdo1 } else { &self.rpdo2 };
        let mut buf = [0u8; 8];
        let n = pdo::pack(mapping, &self.od, &mut buf).map_err(|e| format!("pack: {e:?}"))?;
        Ok(buf[..n].to_vec())
    }

    fn statusword(&self) -> u16 {
        match self.od.read(STATUSWORD) {
            Ok(Value::Unsigned16(v)) => v,
            _ => 0,
        }
    }

    fn position(&self) -> i32 {
        match self.od.read(POSITION_ACTUAL) {
            Ok(Value::Integer32(v)) => v,
            _ => 0,
        }
    }
}

struct Master {
    bus: UdpCan,
    node: NodeId,
    sdo: SdoClient,
    image: ProcessImage,
    tpdos: u64,
    emcy: Vec<EmergencyMessage>,
    heartbeats: Vec<NmtState>,
    sync_running: bool,
    next_sync: Instant,
}

impl Master {
    /// Handle one received frame (TPDO1, EMCY, heartbeat); other COB-IDs are returned.
    fn dispatch(&mut self, cob: u16, data: &[u8]) -> Option<(u16, Vec<u8>)> {
        let id = self.node.raw() as u16;
        if cob == 0x180 + id {
            if pdo::unpack(&self.image.tpdo1, &mut self.image.od, data).is_ok() {
                self.tpdos += 1;
            }
        } else if cob == 0x80 + id {
            if let Ok(m) = EmergencyMessage::decode(data) {
                self.emcy.push(m);
            }
        } else if cob == nmt::heartbeat_cob_id(self.node) && data.len() == 1 {
            if let Ok(state) = NmtState::from_wire(data[0]) {
                self.heartbeats.push(state);
            }
        } else {
            return Some((cob, data.to_vec()));
        }
        None
    }

    /// Receive until `deadline`, sending the SYNC on time; return the first frame of `want`.
    fn pump(&mut self, deadline: Instant, want: Option<u16>) -> Result<Option<Vec<u8>>, Failure> {
        loop {
            let now = Instant::now();
            if self.sync_running && now >= self.next_sync {
                self.bus.send(0x080, &[])?; // SYNC without a counter
                self.next_sync += SYNC_PERIOD;
                if self.next_sync < now {
                    self.next_sync = now + SYNC_PERIOD;
                }
            }
            if now >= deadline {
                return Ok(None);
            }
            let mut until = deadline;
            if self.sync_running && self.next_sync < until {
                until = self.next_sync;
            }
            let wait = until.saturating_duration_since(Instant::now()).max(Duration::from_micros(100));
            if let Some((cob, data)) = self.bus.recv(wait)? {
                if let Some((cob, data)) = self.dispatch(cob, &data) {
                    if Some(cob) == want {
                        return Ok(Some(data));
                    }
                }
            }
        }
    }

    fn wait(&mut self, duration: Duration) -> Result<(), Failure> {
        self.pump(Instant::now() + duration, None).map(|_| ())
    }

    /// One SDO transaction with the canopen-rs client: Ok(value) or Err(abort code).
    fn sdo(&mut self, first: [u8; 8]) -> Result<Result<Option<Value>, u32>, Failure> {
        let id = self.node.raw() as u16;
        let mut frame = first;
        loop {
            self.bus.send(self.sdo.request_cob_id(), &frame)?;
            let reply = self.pump(Instant::now() + Duration::from_secs(2), Some(0x580 + id))?;
            let reply = reply.ok_or_else(|| "SDO: no response within 2 s".to_string())?;
            let mut payload = [0u8; 8];
            let n = reply.len().min(8);
            payload[..n].copy_from_slice(&reply[..n]);
            match self.sdo.on_response(&payload) {
                SdoEvent::Send(next) => frame = next,
                SdoEvent::Complete(value) => return Ok(Ok(value)),
                SdoEvent::Aborted(code) => return Ok(Err(code)),
            }
        }
    }

    fn read(&mut self, index: u16, subindex: u8, data_type: DataType) -> Result<Value, Failure> {
        let first = self.sdo.read(Address::new(index, subindex), data_type);
        match self.sdo(first)? {
            Ok(Some(value)) => Ok(value),
            Ok(None) => Err(format!("SDO read {index:04X}:{subindex:02X}: no value")),
            Err(code) => Err(format!("SDO read {index:04X}:{subindex:02X}: abort 0x{code:08X}")),
        }
    }

    fn write(&mut self, index: u16, subindex: u8, value: Value) -> Result<(), Failure> {
        let first = self.sdo.write(Address::new(index, subindex), value);
        match self.sdo(first)? {
            Ok(_) => Ok(()),
            Err(code) => Err(format!("SDO write {index:04X}:{subindex:02X}: abort 0x{code:08X}")),
        }
    }

    fn nmt(&mut self, command: NmtCommand) -> Result<(), Failure> {
        let frame = nmt::encode_command(command, self.node);
        self.bus.send(0x000, &frame)
    }

    fn controlword(&mut self, controlword: u16) -> Result<(), Failure> {
        let data = self.image.pack(1, &[(CONTROLWORD, Value::Unsigned16(controlword)),
                                        (MODES_OF_OPERATION, Value::Integer8(CSP))])?;
        self.bus.send(0x200 + self.node.raw() as u16, &data)
    }

    fn target(&mut self, position: i32, velocity: i32) -> Result<(), Failure> {
        let data = self.image.pack(2, &[(TARGET_POSITION, Value::Integer32(position)),
                                        (VELOCITY_OFFSET, Value::Integer32(velocity))])?;
        self.bus.send(0x300 + self.node.raw() as u16, &data)
    }

    /// Wait until the statusword from TPDO1 matches `value` under `mask`.
    fn wait_statusword(&mut self, mask: u16, value: u16, what: &str) -> Result<u16, Failure> {
        let deadline = Instant::now() + Duration::from_secs(2);
        while Instant::now() < deadline {
            let before = self.tpdos;
            self.pump(Instant::now() + SYNC_PERIOD * 2, None)?;
            if self.tpdos > before && self.image.statusword() & mask == value {
                return Ok(self.image.statusword());
            }
        }
        Err(format!("statusword 0x{:04X} is not {what}", self.image.statusword()))
    }

    /// Stream a ramp of targets from `start`, one per SYNC; return the last target.
    fn stream(&mut self, start: i32, count: i32) -> Result<i32, Failure> {
        let mut last = start;
        for k in 0..count {
            last = start + 20 * k;
            self.target(last, 10_000)?;
            let next = self.next_sync;
            self.pump(next + Duration::from_micros(200), None)?;
        }
        self.wait(SYNC_PERIOD * 10)?;
        Ok(last)
    }
}

fn run(node_id: u8) -> Result<(), Failure> {
    let node = NodeId::new(node_id).map_err(|e| format!("{e:?}"))?;
    let bus = UdpCan::open("239.74.163.2", 43113)?;
    let mut m = Master {
        bus, node, sdo: SdoClient::new(node), image: ProcessImage::new()?, tpdos: 0,
        emcy: Vec::new(), heartbeats: Vec::new(), sync_running: false, next_sync: Instant::now(),
    };

    // NMT: the drive's heartbeat, then a reset of communication and its boot-up.
    step("listening");
    let heartbeat = nmt::heartbeat_cob_id(node);
    let deadline = Instant::now() + Duration::from_secs(10);
    while m.heartbeats.is_empty() && Instant::now() < deadline {
        m.wait(Duration::from_millis(5))?;
    }
    check!(!m.heartbeats.is_empty(), "no heartbeat (0x{heartbeat:03X}) within 10 s");
    m.nmt(NmtCommand::ResetCommunication)?;
    let deadline = Instant::now() + Duration::from_secs(2);
    while !m.heartbeats.contains(&NmtState::Initialising) && Instant::now() < deadline {
        m.wait(Duration::from_millis(5))?;
    }
    check!(m.heartbeats.contains(&NmtState::Initialising), "no boot-up after NMT reset communication");
    step("boot-up after NMT reset communication");

    // SDO: expedited and segmented uploads, an abort, an expedited download.
    let device_type = m.read(0x1000, 0, DataType::Unsigned32)?;
    check!(device_type == Value::Unsigned32(DEVICE_TYPE_SERVO), "device type {device_type:?}");
    let message = m.read(0x2001, 4, DataType::VisibleString)?; // 8 bytes: segmented
    check!(matches!(&message, Value::VisibleString(s) if s.as_str() == Some("no error")), "0x2001:04 {message:?}");
    let first = m.sdo.read(Address::new(0x5000, 0), DataType::Unsigned32);
    check!(m.sdo(first)? == Err(0x0602_0000), "object 0x5000 should not exist");
    m.write(0x1017, 0, Value::Unsigned16(50))?; // heartbeat every 50 ms
    step("sdo: expedited and segmented upload, abort 0x06020000, download");

    // A segmented download that is no cam table: the drive refuses it (CiA 301 0x08000020) and
    // says why in 0x2001:04 (a segmented upload).
    let first = m.sdo.write(Address::new(0x2000, 0), Value::Domain(
        canopen_rs::datatypes::ByteString::from_bytes(b"not a cam table, 28 bytes..").map_err(|e| format!("{e:?}"))?));
    check!(m.sdo(first)? == Err(0x0800_0020), "a bad cam table download should abort with 0x08000020");
    // The cam status says the last download was refused (bit 2) and with which code.
    let status = m.read(0x2001, 2, DataType::Unsigned8)?;
    check!(matches!(status, Value::Unsigned8(s) if s & 0x04 != 0), "cam status {status:?}");
    let code = m.read(0x2001, 3, DataType::Unsigned32)?;
    check!(code == Value::Unsigned32(0x0800_0020), "cam last error code {code:?}");
    step("segmented download refused: abort 0x08000020, cam status says so");

    // PDOs configured by SDO (CiA 301: invalidate, map, validate), mapping entries by canopen-rs.
    let id = node_id as u32;
    let configure = |m: &mut Master, comm: u16, map: u16, cob: u32, trans: u8, items: Items| -> Result<(), Failure> {
        let mapping = mapping(items)?;
        m.write(comm, 1, Value::Unsigned32(0x8000_0000 | cob))?;
        m.write(map, 0, Value::Unsigned8(0))?;
        for (sub, entry) in mapping.entries().iter().enumerate() {
            m.write(map, sub as u8 + 1, Value::Unsigned32(entry.to_u32()))?;
        }
        m.write(map, 0, Value::Unsigned8(mapping.len() as u8))?;
        m.write(comm, 2, Value::Unsigned8(trans))?;
        m.write(comm, 1, Value::Unsigned32(cob))
    };
    configure(&mut m, 0x1400, 0x1600, 0x200 + id, 0xFF, RPDO1)?;
    configure(&mut m, 0x1401, 0x1601, 0x300 + id, 0x01, RPDO2)?;
    configure(&mut m, 0x1800, 0x1A00, 0x180 + id, 0x01, TPDO1)?;
    let entry = m.read(0x1A00, 2, DataType::Unsigned32)?;
    check!(entry == Value::Unsigned32(0x6064_0020), "0x1A00:02 {entry:?}");
    step("pdo mapping written by sdo");

    // NMT start, SYNC, CSP, the CiA 402 state machine by RPDO1, watched in TPDO1.
    m.write(0x6060, 0, Value::Integer8(CSP))?;
    m.nmt(NmtCommand::StartRemoteNode)?;
    m.sync_running = true;
    m.next_sync = Instant::now();
    m.wait(Duration::from_millis(60))?;
    check!(m.heartbeats.last() == Some(&NmtState::Operational), "heartbeat {:?}", m.heartbeats.last());
    m.wait_statusword(0x4F, 0x40, "SWITCH ON DISABLED")?;
    m.controlword(0x06)?;
    m.wait_statusword(0x6F, 0x21, "READY TO SWITCH ON")?;
    m.controlword(0x07)?;
    m.wait_statusword(0x6F, 0x23, "SWITCHED ON")?;
    let position = m.image.position();
    m.target(position, 0)?;
    m.controlword(0x0F)?;
    let statusword = m.wait_statusword(0x6F, 0x27, "OPERATION ENABLED")?;
    step(&format!("operational, operation enabled in CSP, statusword 0x{statusword:04X}"));

    // Stream targets by RPDO2, read the position from TPDO1.
    let start = m.image.position();
    let last = m.stream(start, 300)?;
    let actual = m.image.position();
    check!((actual - last).abs() < 1000, "position {actual} after streaming to {last}");
    step(&format!("streamed 300 targets, position by TPDO {actual} (target {last})"));

    // A following-error fault: EMCY 0x8611, FAULT; fault reset and re-enable.
    m.emcy.clear();
    m.target(actual.wrapping_add(1 << 29), 0)?;
    m.wait_statusword(0x4F, 0x08, "FAULT")?;
    let emcy = m.emcy.iter().find(|e| e.error_code == EMCY_FOLLOWING_ERROR).copied();
    check!(emcy.is_some(), "no following-error EMCY: {:?}", m.emcy);
    step(&format!("emcy 0x{:04X}, register 0x{:02X}, fault", EMCY_FOLLOWING_ERROR, emcy.unwrap().error_register.0));
    let position = m.image.position();
    m.target(position, 0)?;
    m.controlword(0x0F | 0x80)?; // rising edge of fault reset
    m.wait_statusword(0x4F, 0x40, "SWITCH ON DISABLED after the fault reset")?;
    check!(m.emcy.iter().any(|e| e.is_error_reset()), "no error-reset EMCY");
    m.controlword(0x06)?;
    m.wait_statusword(0x6F, 0x21, "READY TO SWITCH ON")?;
    m.controlword(0x0F)?;
    m.wait_statusword(0x6F, 0x27, "OPERATION ENABLED again")?;
    let start = m.image.position();
    let last = m.stream(start, 100)?;
    let actual = m.image.position();
    check!((actual - last).abs() < 1000, "position {actual} after streaming to {last}");
    step("fault reset and re-enabled, following again");

    // SYNC supervision: 0x1006 arms it, 0x6007 = 1 (the default) faults when the SYNC stops.
    m.write(0x1006, 0, Value::Unsigned32(SYNC_PERIOD.as_micros() as u32))?;
    m.emcy.clear();
    m.sync_running = false;
    let deadline = Instant::now() + Duration::from_secs(2);
    while !m.emcy.iter().any(|e| e.error_code == EMCY_SYNC_LOST) && Instant::now() < deadline {
        m.wait(Duration::from_millis(5))?;
    }
    check!(m.emcy.iter().any(|e| e.error_code == EMCY_SYNC_LOST), "no EMCY 0x8100 when the SYNC stopped");
    m.wait(Duration::from_millis(20))?;
    let statusword = m.read(0x6041, 0, DataType::Unsigned16)?; // no SYNC: no TPDO, ask by SDO
    check!(matches!(statusword, Value::Unsigned16(w) if w & 0x4F == 0x08), "statusword {statusword:?} after the SYNC stopped");
    step("sync lost: emcy 0x8100, fault");

    // NMT stop: the heartbeat reports STOPPED.
    m.nmt(NmtCommand::StopRemoteNode)?;
    m.heartbeats.clear();
    m.wait(Duration::from_millis(150))?;
    check!(m.heartbeats.last() == Some(&NmtState::Stopped), "heartbeat {:?} after NMT stop", m.heartbeats.last());
    step("nmt stopped");
    Ok(())
}

fn main() -> ExitCode {
    let node_id = std::env::args().nth(1).and_then(|a| a.parse().ok()).unwrap_or(3);
    match run(node_id) {
        Ok(()) => {
            println!("ok");
            ExitCode::SUCCESS
        }
        Err(failure) => {
            println!("failed: {failure}");
            ExitCode::FAILURE
        }
    }
}
