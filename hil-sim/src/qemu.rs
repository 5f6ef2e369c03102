//! The QEMU brain: the real firmware ELF on an emulated Cortex-M4F (`mps2-an386`), one
//! QEMU process per robot. The lockstep link (`protocol::body`) carries everything: the
//! simulator sends the time, the sensors and exactly the bytes the simulated radio
//! delivered; the firmware answers with the bytes it transmitted and the motor duties once
//! everything due by then has run. The link is two FIFOs the firmware opens through
//! semihosting (a period's bytes in one host call each way). QEMU runs with `-icount`
//! (deterministic instruction timing; SysTick then measures instructions), but the
//! firmware's clock is the simulator's, so a run is reproducible and as fast as the
//! firmware computes, whatever else the machine is doing.
//!
//! QEMU is killed when the brain is dropped (also on a panic) and when the harness process
//! dies (`PR_SET_PDEATHSIG`). A firmware that crashes or hangs fails the run with its last
//! defmt lines (decoded from semihosting output with the ELF's table).

use std::collections::VecDeque;
use std::fs::File;
use std::io::{self, Read, Write};
use std::os::fd::AsRawFd;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use control_core::controller::{MotorOutput, Sensors};
use protocol::body::{
    self, BodyConfig, BodySensors, FirmwareFault, FromMcu, Step, ToMcu, MAX_BODY_FRAME,
    MAX_RADIO_CHUNK,
};
use protocol::messages::RobotMode;
use protocol::{frame, FrameDecoder, Message, RejectCounts};

use crate::brain::{Brain, BrainError};

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
    /// The directory holding the link's FIFOs (QEMU's working directory).
    dir: PathBuf,
    to_mcu: File,
    from_mcu: File,
    inbox: Vec<u8>,
    rx_written: u32,
    tx_read: u32,
    logs: Arc<Mutex<VecDeque<String>>>,
    scan: FrameDecoder,
    mode: RobotMode,
    rejects: RejectCounts,
    /// SysTick counts of every control step (25 MHz virtual clock).
    step_cycles: Vec<u32>,
    /// SysTick counts spent receiving radio frames, per control period.
    rx_cycles: Vec<u32>,
    /// Receive counts of the steps since the last control step (a frame may arrive
    /// between two ticks).
    rx_pending: u32,
    timeout: Duration,
}

/// A FIFO the harness holds open for reading and writing: opening never blocks, and it
/// stays valid whether or not QEMU has opened its end yet.
fn fifo(path: &Path) -> io::Result<File> {
    let c = std::ffi::CString::new(path.as_os_str().as_bytes())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "NUL in a temp path"))?;
    // SAFETY: a valid NUL-terminated path.
    if unsafe { libc::mkfifo(c.as_ptr(), 0o600) } != 0 {
        return Err(io::Error::last_os_error());
    }
    File::options().read(true).write(true).open(path)
}

/// Waits until `file` has bytes to read, in short polls so that a QEMU that exits is
/// noticed at once; an error after `timeout`.
fn wait_readable(file: &File, child: &mut Child, timeout: Duration) -> io::Result<()> {
    let deadline = Instant::now() + timeout;
    loop {
        let mut fd = libc::pollfd {
            fd: file.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one valid pollfd.
        let ready = unsafe { libc::poll(&mut fd, 1, 20) };
        if ready > 0 {
            return Ok(());
        }
        if ready < 0 {
            let e = io::Error::last_os_error();
            if e.kind() != io::ErrorKind::Interrupted {
                return Err(e);
            }
        }
        if let Ok(Some(_)) = child.try_wait() {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        if Instant::now() > deadline {
            return Err(io::ErrorKind::TimedOut.into());
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

/// A fresh working directory for robot `id`'s QEMU (unique per brain: several worlds may
/// run in one process, tests in parallel) with its two lockstep FIFOs.
fn lockstep_dir(id: u16) -> Result<(PathBuf, File, File), String> {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("sweeper-{}-{n}-{id}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let fifos =
        fifo(&dir.join("lockstep.in")).and_then(|i| Ok((i, fifo(&dir.join("lockstep.out"))?)));
    match fifos {
        Ok((to_mcu, from_mcu)) => Ok((dir, to_mcu, from_mcu)),
        Err(e) => {
            let _ = std::fs::remove_dir_all(&dir);
            Err(format!(
                "cannot make the lockstep FIFOs in {}: {e}",
                dir.display()
            ))
        }
    }
}

/// QEMU on the mps2-an386 board with the firmware `elf`, in `dir`: semihosting for defmt
/// on its standard output, deterministic instruction counting, killed with the harness.
fn start_qemu(elf: &Path, dir: &Path) -> io::Result<std::process::Child> {
    let mut cmd = Command::new("qemu-system-arm");
    cmd.args([
        "-M",
        "mps2-an386",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "null",
    ])
    .args(["-semihosting-config", "enable=on,target=native"])
    .args(["-icount", "shift=5,align=off,sleep=off"])
    .arg("-kernel")
    .arg(elf)
    .current_dir(dir)
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
    cmd.spawn()
}

impl QemuBrain {
    /// Boots one robot's firmware and configures it (what its flash page holds).
    pub fn spawn(elf: &Path, config: BodyConfig, timeout: Duration) -> Result<Self, BrainError> {
        let id = config.id;
        let err = |m: String| BrainError(format!("robot {id}: {m}"));
        let image = std::fs::read(elf).map_err(|e| {
            err(format!(
                "cannot read the firmware {}: {e} (build it: ./scripts/build-firmware.sh)",
                elf.display()
            ))
        })?;
        let elf = std::fs::canonicalize(elf).map_err(|e| err(e.to_string()))?;
        let (dir, to_mcu, from_mcu) = lockstep_dir(id).map_err(err)?;
        let mut child = match start_qemu(&elf, &dir) {
            Ok(c) => c,
            Err(e) => {
                let _ = std::fs::remove_dir_all(&dir);
                return Err(if e.kind() == io::ErrorKind::NotFound {
                    err("qemu-system-arm not found: install it (Debian/Ubuntu: `sudo apt-get install qemu-system-arm`)".into())
                } else {
                    err(format!("cannot start QEMU: {e}"))
                });
            }
        };
        let logs = Arc::new(Mutex::new(VecDeque::new()));
        if let Some(out) = child.stdout.take() {
            log_reader(id, image, out, logs.clone());
        }
        let mut brain = Self {
            id,
            child,
            dir,
            to_mcu,
            from_mcu,
            inbox: Vec::new(),
            rx_written: 0,
            tx_read: 0,
            logs,
            scan: FrameDecoder::new(),
            mode: RobotMode::Idle,
            rejects: RejectCounts::default(),
            step_cycles: Vec::new(),
            rx_cycles: Vec::new(),
            rx_pending: 0,
            timeout,
        };
        let config = ToMcu::Config(config);
        let mut out = Vec::new();
        push(&mut out, &config)?;
        brain.send(&out)?;
        let mut frame = brain.next_frame()?;
        match body::decode::<FromMcu>(&mut frame) {
            Ok(FromMcu::Ready) => Ok(brain),
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
            | io::ErrorKind::BrokenPipe => "stopped (crashed?)".to_string(),
            _ => format!("link failed: {e}"),
        };
        self.failure(&what)
    }

    fn send(&mut self, bytes: &[u8]) -> Result<(), BrainError> {
        self.to_mcu.write_all(bytes).map_err(|e| self.io_failure(e))
    }

    /// The next COBS frame from the firmware (its delimiter dropped).
    fn next_frame(&mut self) -> Result<Vec<u8>, BrainError> {
        let mut buf = [0u8; 4096];
        loop {
            if let Some(end) = self.inbox.iter().position(|b| *b == 0) {
                let mut frame: Vec<u8> = self.inbox.drain(..=end).collect();
                frame.pop();
                return Ok(frame);
            }
            if let Err(e) = wait_readable(&self.from_mcu, &mut self.child, self.timeout) {
                return Err(self.io_failure(e));
            }
            match self.from_mcu.read(&mut buf) {
                Ok(n) => self.inbox.extend_from_slice(&buf[..n]),
                Err(e) => return Err(self.io_failure(e)),
            }
        }
    }

    /// Watches the robot's own frames for its telemetry (its mode).
    fn scan_tx(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(Ok(raw)) = self.scan.push(b) {
                if let Ok((_, Message::Telemetry(t))) = frame::parse_unverified(raw) {
                    self.mode = t.mode;
                }
            }
        }
    }
}

/// Appends a body message's COBS frame to `out`.
fn push(out: &mut Vec<u8>, msg: &ToMcu) -> Result<(), BrainError> {
    let mut buf = [0u8; MAX_BODY_FRAME];
    let n = body::encode(msg, &mut buf).map_err(|e| BrainError(format!("body frame: {e}")))?;
    out.extend_from_slice(&buf[..n]);
    Ok(())
}

impl Brain for QemuBrain {
    fn step_start(
        &mut self,
        local_us: u64,
        radio: &[u8],
        sensors: Option<&Sensors>,
    ) -> Result<(), BrainError> {
        // The step first, then its radio bytes: the firmware moves its clock to the step's
        // time and processes the bytes at that time, as the native brain does. One write.
        let rx_written = self.rx_written.wrapping_add(radio.len() as u32);
        let step = Step {
            time_us: local_us,
            radio_rx_bytes: rx_written,
            sensors: sensors.map(|s| BodySensors {
                ticks: s.ticks,
                pose_fix: s
                    .pose_fix
                    .map(|f| (f.pose.x, f.pose.y, f.pose.heading, f.sigma, f.time_ms)),
                proximity: s.proximity,
            }),
        };
        let mut out = Vec::with_capacity(64 + radio.len() * 2);
        push(&mut out, &ToMcu::Step(step))?;
        for chunk in radio.chunks(MAX_RADIO_CHUNK) {
            push(&mut out, &ToMcu::Radio(chunk))?;
        }
        self.send(&out)?;
        self.rx_written = rx_written;
        Ok(())
    }

    fn step_finish(&mut self, tx: &mut Vec<u8>) -> Result<Option<MotorOutput>, BrainError> {
        let start = tx.len();
        let done = loop {
            let mut frame = self.next_frame()?;
            match body::decode::<FromMcu>(&mut frame) {
                Ok(FromMcu::Radio(bytes)) => tx.extend_from_slice(bytes),
                Ok(FromMcu::Done(d)) => break d,
                Ok(FromMcu::Ready) => continue,
                Err(e) => return Err(self.failure(&format!("sent a malformed body frame ({e})"))),
            }
        };
        let sent = (tx.len() - start) as u32;
        if done.radio_tx_bytes.wrapping_sub(self.tx_read) != sent {
            return Err(self.failure(&format!(
                "counts {} radio bytes sent since the last step, the link carried {sent}",
                done.radio_tx_bytes.wrapping_sub(self.tx_read)
            )));
        }
        self.tx_read = done.radio_tx_bytes;
        self.rejects = done.rejects;
        self.scan_tx(&tx[start..]);
        if !done.duty.iter().all(|d| d.is_finite()) {
            return Err(self.failure("sent a non-finite motor duty"));
        }
        self.rx_pending = self.rx_pending.saturating_add(done.rx_cycles);
        if done.ticked {
            self.step_cycles.push(done.step_cycles);
            self.rx_cycles.push(std::mem::take(&mut self.rx_pending));
        }
        Ok(done.ticked.then_some(MotorOutput { duty: done.duty }))
    }

    fn mode(&self) -> RobotMode {
        self.mode
    }

    fn rejects(&self) -> RejectCounts {
        self.rejects
    }

    fn step_cycles(&self) -> Vec<u32> {
        self.step_cycles.clone()
    }

    fn rx_cycles(&self) -> Vec<u32> {
        self.rx_cycles.clone()
    }

    fn inject(&mut self, fault: FirmwareFault) -> Result<(), BrainError> {
        let mut out = Vec::new();
        push(&mut out, &ToMcu::Inject(fault))?;
        self.send(&out)
    }
}

impl Drop for QemuBrain {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
