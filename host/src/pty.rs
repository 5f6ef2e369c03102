//! A pseudo-terminal pair that behaves as a serial radio modem: the simulated robots'
//! side of `basestation robots --pty`, one more [`Transport`] (its device is what
//! `run --port` opens).

use std::io;
use std::os::fd::{AsFd, OwnedFd};
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use base_station::transport::Transport;

/// The master side; the slave is kept open so that the master keeps working while `run`
/// closes and reopens the device.
pub struct Pty {
    master: OwnedFd,
    slave: OwnedFd,
}

impl Pty {
    /// A raw pair (the protocol's bytes pass untouched: no echo, no CR/LF mapping), the
    /// master non-blocking.
    pub fn open() -> anyhow::Result<Self> {
        use nix::fcntl::{fcntl, FcntlArg, OFlag};
        use nix::sys::termios;
        let pair = nix::pty::openpty(None, None).context("cannot open a pseudo-terminal")?;
        for fd in [&pair.master, &pair.slave] {
            let mut t = termios::tcgetattr(fd.as_fd())?;
            termios::cfmakeraw(&mut t);
            termios::tcsetattr(fd.as_fd(), termios::SetArg::TCSANOW, &t)?;
        }
        fcntl(&pair.master, FcntlArg::F_SETFL(OFlag::O_NONBLOCK))?;
        Ok(Self {
            master: pair.master,
            slave: pair.slave,
        })
    }

    /// The device `run --port` opens.
    pub fn path(&self) -> anyhow::Result<PathBuf> {
        nix::unistd::ttyname(self.slave.as_fd()).context("the pty has no name")
    }
}

impl Transport for Pty {
    /// A modem with nobody reading drops what its buffer cannot hold.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let mut rest = bytes;
        while !rest.is_empty() {
            match nix::unistd::write(&self.master, rest) {
                Ok(n) => rest = &rest[n..],
                Err(nix::errno::Errno::EAGAIN) => break,
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
    }

    /// What is waiting now: the master never blocks, whatever `timeout` says.
    fn recv(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
        match nix::unistd::read(&self.master, buf) {
            Ok(n) => Ok(n),
            Err(nix::errno::Errno::EAGAIN) => Ok(0),
            Err(e) => Err(e.into()),
        }
    }

    fn describe(&self) -> String {
        self.path().map_or("this pseudo-terminal".into(), |p| {
            format!("pty {}", p.display())
        })
    }
}
