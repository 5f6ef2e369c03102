//! The byte pipes the base station speaks through: a serial port (a USB radio modem or a
//! UART) or UDP. Both carry the protocol's COBS frames unchanged.

use std::io::{self, Read, Write};
use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

/// A byte pipe to the fleet.
pub trait Transport {
    /// Sends bytes (whole frames).
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Reads what is available within `timeout` (0 bytes when nothing came).
    fn recv(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
}

pub struct Serial {
    port: Box<dyn serialport::SerialPort>,
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
        Ok(Self { port })
    }
}

impl Transport for Serial {
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
        self.socket
            .set_read_timeout(Some(timeout.max(Duration::from_millis(1))))?;
        match self.socket.recv_from(buf) {
            Ok((n, _)) => Ok(n),
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
                Ok(0)
            }
            Err(e) => Err(e),
        }
    }
}
