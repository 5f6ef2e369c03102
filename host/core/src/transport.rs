//! The byte pipes the fleet speaks through, one abstraction for every link: a serial port
//! (a USB radio modem or a UART), UDP to a radio bridge, and UDP answering whoever spoke
//! last (the simulated robots' side, `basestation robots`). Each carries the protocol's
//! COBS frames unchanged.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

/// A byte pipe to the fleet.
pub trait Transport {
    /// Sends bytes (whole frames).
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads what is available within `timeout` (0 bytes when nothing came; a zero
    /// `timeout` does not wait).
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Where the link is, for the operator: `serial /dev/ttyUSB0`, `udp 10.0.0.5:7000`.
    fn describe(&self) -> String;
}

pub struct Serial {
    port: Box<dyn serialport::SerialPort>,
    name: String,
}

impl Serial {
    pub fn open(path: &str, baud: u32) -> io::Result<Self> {
        let port = serialport::new(path, baud)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(io::Error::other)?;
        // What the port holds from before we opened it is stale: a robot's handshake
        // answered seconds late would set its clock offset off by half that wait.
        port.clear(serialport::ClearBuffer::Input)
            .map_err(io::Error::other)?;
        Ok(Self {
            name: port.name().unwrap_or_else(|| path.to_string()),
            port,
        })
    }
}

impl Transport for Serial {
    fn describe(&self) -> String {
        format!("serial {}", self.name)
    }

    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.port.set_timeout(timeout).map_err(io::Error::other)?;
        match self.port.read(buf) {
            Ok(n) => Ok(n),
            // A signal (Ctrl-C, SIGTERM) is the caller's to handle, not an error.
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(0)
            }
            Err(e) => Err(e),
        }
    }
}

/// UDP: datagrams to `peer` (a radio bridge, or a broadcast address), from anyone.
pub struct Udp {
    socket: UdpSocket,
    peer: SocketAddr,
}

impl Udp {
    pub fn open(bind: SocketAddr, peer: SocketAddr) -> io::Result<Self> {
        let socket = UdpSocket::bind(bind)?;
        if peer.ip().is_unspecified() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "peer address is unspecified",
            ));
        }
        socket.set_broadcast(true)?;
        Ok(Self { socket, peer })
    }

    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
}

impl Transport for Udp {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        // One datagram per write; a datagram may hold several frames.
        for chunk in bytes.chunks(1200) {
            match self.socket.send_to(chunk, self.peer) {
                // An earlier datagram found nobody listening (ICMP): the bridge may come
                // back; not an error of this send.
                Err(e) if e.kind() == io::ErrorKind::ConnectionRefused => {}
                r => {
                    r?;
                }
            }
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        Ok(recv_within(&self.socket, buf, timeout)?.map_or(0, |(n, _)| n))
    }

    fn describe(&self) -> String {
        format!("udp {}", self.peer)
    }
}

/// One datagram within `timeout` (`None`: none came; zero: do not wait).
fn recv_within(
    socket: &UdpSocket,
    buf: &mut [u8],
    timeout: Duration,
) -> io::Result<Option<(usize, SocketAddr)>> {
    if timeout.is_zero() {
        socket.set_nonblocking(true)?;
    } else {
        socket.set_nonblocking(false)?;
        socket.set_read_timeout(Some(timeout))?;
    }
    match socket.recv_from(buf) {
        Ok(got) => Ok(Some(got)),
        Err(e)
            if matches!(
                e.kind(),
                io::ErrorKind::WouldBlock
                    | io::ErrorKind::TimedOut
                    | io::ErrorKind::Interrupted
                    // An earlier datagram's receiver was not there (ICMP): not ours.
                    | io::ErrorKind::ConnectionRefused
            ) =>
        {
            Ok(None)
        }
        Err(e) => Err(e),
    }
}

/// UDP on a bound address, answering whoever sent the last datagram (until someone does,
/// what is sent goes nowhere, as on the air): the robots' side of `--udp`.
pub struct UdpAnswer {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
}

impl UdpAnswer {
    pub fn bind(addr: SocketAddr) -> io::Result<Self> {
        Ok(Self {
            socket: UdpSocket::bind(addr)?,
            peer: None,
        })
    }

    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
}

impl Transport for UdpAnswer {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let Some(peer) = self.peer else {
            return Ok(());
        };
        self.socket.set_nonblocking(true)?;
        for chunk in bytes.chunks(1200) {
            match self.socket.send_to(chunk, peer) {
                // A full socket buffer or a peer gone: the air drops it.
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::ConnectionRefused
                    ) => {}
                r => {
                    r?;
                }
            }
        }
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        Ok(match recv_within(&self.socket, buf, timeout)? {
            Some((n, from)) => {
                self.peer = Some(from);
                n
            }
            None => 0,
        })
    }

    fn describe(&self) -> String {
        self.local_addr()
            .map_or("this UDP socket".into(), |a| format!("udp {a}"))
    }
}
