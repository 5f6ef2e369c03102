//! The QEMU brain: the real firmware ELF on an emulated Cortex-M4F (`mps2-an386`), one
//! QEMU process per robot. The robot's radio UART is a socket carrying exactly the bytes
//! the simulated radio delivers; its body UART is the lockstep link (`protocol::body`):
//! the simulator sends the time and the sensors, the firmware answers with the motor
//! duties once everything due by then has run. QEMU runs with `-icount` (deterministic
//! instruction timing; SysTick then measures instructions), but the firmware's clock is
//! the simulator's, so a run is reproducible and as fast as the firmware computes.
//!
//! QEMU is killed when the brain is dropped (also on a panic) and when the harness process
//! dies (`PR_SET_PDEATHSIG`). A firmware that crashes or hangs fails the run with its last
//! defmt lines (decoded from semihosting output with the ELF's table).

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use control_core::controller::{MotorOutput, Sensors};
use protocol::body::{
    self, BodyConfig, BodySensors, FirmwareFault, FromMcu, Step, ToMcu, MAX_BODY_FRAME,
};
use protocol::messages::RobotMode;
use protocol::{frame, FrameDecoder, Message};

use crate::brain::{Brain, BrainError, BrainRejects};

/// How long a firmware may take to answer one step (wall clock) before it counts as hung,
/// unless the run says otherwise.
pub const STEP_TIMEOUT: Duration = Duration::from_secs(10);
/// defmt lines kept per robot to show when it fails.
const LOG_LINES: usize = 40;

/// Where the QEMU firmware ELF is: `SWEEPER_FIRMWARE_ELF`, else the build script's output.
pub fn firmware_elf() -> PathBuf {
    std::env::var_os("SWEEPER_FIRMWARE_ELF")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../firmware/mcu/target/qemu/thumbv7em-none-eabihf/release/sweeper-firmware")
        })
}

pub struct QemuBrain {
    id: u16,
    child: Child,
    radio: UnixStream,
    body: UnixStream,
    body_buf: Vec<u8>,
    rx_written: u32,
    tx_read: u32,
    logs: Arc<Mutex<VecDeque<String>>>,
    scan: FrameDecoder,
    mode: RobotMode,
    rejected: u32,
    /// SysTick counts of every control step (25 MHz virtual clock).
    step_cycles: Vec<u32>,
    /// SysTick counts spent receiving radio frames, per control period.
    rx_cycles: Vec<u32>,
    timeout: Duration,
}

/// A Unix socket QEMU connects to as a client (bytes written before it connects would be
/// lost the other way round). Unix sockets: QEMU writes a byte per write, and loopback TCP
/// costs a packet per byte.
fn listen(path: &Path) -> io::Result<UnixListener> {
    let _ = std::fs::remove_file(path);
    let l = UnixListener::bind(path)?;
    l.set_nonblocking(true)?;
    Ok(l)
}

fn accept(l: &UnixListener, child: &mut Child, deadline: Instant) -> Result<UnixStream, String> {
    loop {
        match l.accept() {
            Ok((s, _)) => {
                s.set_nonblocking(false).map_err(|e| e.to_string())?;
                return Ok(s);
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                if let Ok(Some(status)) = child.try_wait() {
                    return Err(format!("QEMU exited before connecting ({status})"));
                }
                if Instant::now() > deadline {
                    return Err("QEMU did not connect within 10 s".into());
                }
                std::thread::sleep(Duration::from_millis(2));
            }
            Err(e) => return Err(e.to_string()),
        }
    }
}

/// Decodes the firmware's defmt output (QEMU's stdout) into lines tagged with the robot.
fn log_reader(
    id: u16,
    elf: Vec<u8>,
    mut stdout: impl Read + Send + 'static,
    logs: Arc<Mutex<VecDeque<String>>>,
) {
    std::thread::spawn(move || {
        let table = match defmt_decoder::Table::parse(&elf) {
            Ok(Some(t)) => t,
            _ => {
                logs.lock()
                    .unwrap()
                    .push_back("(no defmt table in the ELF)".into());
                return;
            }
        };
        let mut decoder = table.new_stream_decoder();
        let mut buf = [0u8; 1024];
        while let Ok(n) = stdout.read(&mut buf) {
            if n == 0 {
                break;
            }
            decoder.received(&buf[..n]);
            loop {
                match decoder.decode() {
                    Ok(frame) => {
                        let line = format!("robot {id}: {}", frame.display(false));
                        tracing::info!(target: "firmware", "{line}");
                        let mut l = logs.lock().unwrap();
                        if l.len() == LOG_LINES {
                            l.pop_front();
                        }
                        l.push_back(line);
                    }
                    Err(defmt_decoder::DecodeError::UnexpectedEof) => break,
                    Err(defmt_decoder::DecodeError::Malformed) => {
                        logs.lock()
                            .unwrap()
                            .push_back(format!("robot {id}: (malformed defmt frame)"));
                        break;
                    }
                }
            }
        }
    });
}

impl QemuBrain {
    /// Boots one robot's firmware and configures it (what its flash page holds).
    pub fn spawn(
        elf: &Path,
        id: u16,
        leader: bool,
        boot_count: u32,
        key: [u8; 32],
        timeout: Duration,
    ) -> Result<Self, BrainError> {
        let err = |m: String| BrainError(format!("robot {id}: {m}"));
        let image = std::fs::read(elf).map_err(|e| {
            err(format!(
                "cannot read the firmware {}: {e} (build it: ./scripts/build-firmware.sh)",
                elf.display()
            ))
        })?;
        let dir = std::env::temp_dir();
        // Unique per brain: several worlds may run in one process (tests in parallel).
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let tag = format!("sweeper-{}-{n}-{id}", std::process::id());
        let (p0, p1) = (
            dir.join(format!("{tag}-radio.sock")),
            dir.join(format!("{tag}-body.sock")),
        );
        let (l0, l1) = (listen(&p0), listen(&p1));
        let (l0, l1) = (
            l0.map_err(|e| err(e.to_string()))?,
            l1.map_err(|e| err(e.to_string()))?,
        );
        let mut cmd = Command::new("qemu-system-arm");
        cmd.args(["-M", "mps2-an386", "-nographic", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"])
            .args(["-icount", "shift=5,align=off,sleep=off"])
            .arg("-kernel")
            .arg(elf)
            .arg("-chardev")
            .arg(format!("socket,id=radio,path={}", p0.display()))
            .args(["-serial", "chardev:radio"])
            .arg("-chardev")
            .arg(format!("socket,id=body,path={}", p1.display()))
            .args(["-serial", "chardev:body"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit());
        // SAFETY: prctl is async-signal-safe; QEMU dies with the harness.
        unsafe {
            cmd.pre_exec(|| {
                libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
                Ok(())
            });
        }
        let mut child = cmd.spawn().map_err(|e| {
            if e.kind() == io::ErrorKind::NotFound {
                err("qemu-system-arm not found: install it (Debian/Ubuntu: `sudo apt-get install qemu-system-arm`)".into())
            } else {
                err(format!("cannot start QEMU: {e}"))
            }
        })?;
        let logs = Arc::new(Mutex::new(VecDeque::new()));
        if let Some(out) = child.stdout.take() {
            log_reader(id, image, out, logs.clone());
        }
        let deadline = Instant::now() + Duration::from_secs(10);
        let radio = accept(&l0, &mut child, deadline).map_err(&err);
        let body = accept(&l1, &mut child, deadline).map_err(&err);
        let _ = std::fs::remove_file(&p0);
        let _ = std::fs::remove_file(&p1);
        let (radio, body) = match (radio, body) {
            (Ok(r), Ok(b)) => (r, b),
            (Err(e), _) | (_, Err(e)) => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(e);
            }
        };
        let _ = body.set_read_timeout(Some(timeout));
        let _ = radio.set_read_timeout(Some(timeout));
        let mut brain = Self {
            id,
            child,
            radio,
            body,
            body_buf: Vec::new(),
            rx_written: 0,
            tx_read: 0,
            logs,
            scan: FrameDecoder::new(),
            mode: RobotMode::Idle,
            rejected: 0,
            step_cycles: Vec::new(),
            rx_cycles: Vec::new(),
            timeout,
        };
        let config = ToMcu::Config(BodyConfig {
            id,
            leader,
            boot_count,
            key,
        });
        brain.send_body(&config)?;
        match brain.read_body()? {
            FromMcu::Ready => Ok(brain),
            other => Err(brain.failure(&format!("expected Ready at boot, got {other:?}"))),
        }
    }

    /// An error that says what happened, with the firmware's last log lines.
    fn failure(&mut self, what: &str) -> BrainError {
        // A crashing firmware exits QEMU through semihosting: give it a moment.
        let mut status = String::new();
        for _ in 0..50 {
            if let Ok(Some(s)) = self.child.try_wait() {
                status = format!(" (QEMU exited: {s})");
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        // Give the log reader a moment to drain a panic message.
        std::thread::sleep(Duration::from_millis(100));
        let logs: Vec<String> = self.logs.lock().unwrap().iter().cloned().collect();
        let tail = if logs.is_empty() {
            "  (no log lines)".to_string()
        } else {
            logs.iter()
                .map(|l| format!("  {l}"))
                .collect::<Vec<_>>()
                .join("\n")
        };
        BrainError(format!(
            "robot {}: firmware {what}{status}; its last log lines:\n{tail}",
            self.id
        ))
    }

    fn io_failure(&mut self, e: io::Error) -> BrainError {
        let what = match e.kind() {
            io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut => {
                format!(
                    "did not answer within {:.1} s (hung?)",
                    self.timeout.as_secs_f64()
                )
            }
            io::ErrorKind::UnexpectedEof
            | io::ErrorKind::ConnectionReset
            | io::ErrorKind::BrokenPipe => "closed its UART (crashed?)".to_string(),
            _ => format!("link failed: {e}"),
        };
        self.failure(&what)
    }

    fn send_body(&mut self, msg: &ToMcu) -> Result<(), BrainError> {
        let mut buf = [0u8; MAX_BODY_FRAME];
        let n = body::encode(msg, &mut buf).map_err(|e| BrainError(format!("body frame: {e}")))?;
        self.body
            .write_all(&buf[..n])
            .map_err(|e| self.io_failure(e))
    }

    fn read_body(&mut self) -> Result<FromMcu, BrainError> {
        let mut byte = [0u8; 64];
        loop {
            if let Some(end) = self.body_buf.iter().position(|b| *b == 0) {
                let mut frame: Vec<u8> = self.body_buf.drain(..=end).collect();
                match body::decode::<FromMcu>(&mut frame) {
                    Ok(msg) => return Ok(msg),
                    Err(_) => continue,
                }
            }
            match self.body.read(&mut byte) {
                Ok(0) => return Err(self.io_failure(io::ErrorKind::UnexpectedEof.into())),
                Ok(n) => self.body_buf.extend_from_slice(&byte[..n]),
                Err(e) => return Err(self.io_failure(e)),
            }
        }
    }

    /// Watches the robot's own frames for its telemetry (mode, rejects).
    fn scan_tx(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(Ok(raw)) = self.scan.push(b) {
                if let Ok((_, Message::Telemetry(t))) = frame::parse_unverified(raw) {
                    self.mode = t.mode;
                    self.rejected = t.link.rejected;
                }
            }
        }
    }
}

impl Brain for QemuBrain {
    fn step_start(
        &mut self,
        local_us: u64,
        radio: &[u8],
        sensors: Option<&Sensors>,
    ) -> Result<(), BrainError> {
        // The step first, then its radio bytes: the firmware moves its clock to the step's
        // time and processes the bytes at that time, as the native brain does.
        let step = Step {
            time_us: local_us,
            radio_rx_bytes: self.rx_written.wrapping_add(radio.len() as u32),
            sensors: sensors.map(|s| BodySensors {
                ticks: s.ticks,
                pose_fix: s
                    .pose_fix
                    .map(|f| (f.pose.x, f.pose.y, f.pose.heading, f.sigma, f.time_ms)),
                proximity: s.proximity,
            }),
        };
        self.send_body(&ToMcu::Step(step))?;
        if !radio.is_empty() {
            self.radio
                .write_all(radio)
                .map_err(|e| self.io_failure(e))?;
            self.rx_written = self.rx_written.wrapping_add(radio.len() as u32);
        }
        Ok(())
    }

    fn step_finish(&mut self, tx: &mut Vec<u8>) -> Result<Option<MotorOutput>, BrainError> {
        let done = loop {
            match self.read_body()? {
                FromMcu::Done(d) => break d,
                FromMcu::Ready => continue,
            }
        };
        let owed = done.radio_tx_bytes.wrapping_sub(self.tx_read) as usize;
        let start = tx.len();
        tx.resize(start + owed, 0);
        if let Err(e) = self.radio.read_exact(&mut tx[start..]) {
            return Err(self.io_failure(e));
        }
        self.tx_read = done.radio_tx_bytes;
        self.scan_tx(&tx[start..]);
        if !done.duty.iter().all(|d| d.is_finite()) {
            return Err(self.failure("sent a non-finite motor duty"));
        }
        if done.ticked {
            self.step_cycles.push(done.step_cycles);
            self.rx_cycles.push(done.rx_cycles);
        }
        Ok(done.ticked.then_some(MotorOutput { duty: done.duty }))
    }

    fn mode(&self) -> RobotMode {
        self.mode
    }

    fn rejects(&self) -> BrainRejects {
        BrainRejects {
            total: self.rejected,
            by_reason: None,
        }
    }

    fn step_cycles(&self) -> Vec<u32> {
        self.step_cycles.clone()
    }

    fn rx_cycles(&self) -> Vec<u32> {
        self.rx_cycles.clone()
    }

    fn inject(&mut self, fault: FirmwareFault) -> Result<(), BrainError> {
        self.send_body(&ToMcu::Inject(fault))
    }
}

impl Drop for QemuBrain {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
