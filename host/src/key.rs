//! The fleet key: from a file only its owner can read, or the environment; never built
//! into the binary. One check for every command that needs it ([`require_key`]).

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use clap::Args;
use protocol::MasterKey;
use zeroize::Zeroizing;

/// Where the fleet key comes from. Never from the binary: a real run without one fails.
#[derive(Args, Debug, Clone)]
pub struct KeyArgs {
    /// File holding the fleet's master key: 64 hexadecimal digits.
    #[arg(long, env = "SWEEPER_KEY_FILE")]
    pub key_file: Option<PathBuf>,
}

impl KeyArgs {
    /// The fleet's master key from `--key-file`, `SWEEPER_KEY_FILE`, or
    /// `SWEEPER_FLEET_KEY` (hex), if any.
    pub fn load(&self) -> anyhow::Result<Option<MasterKey>> {
        let Some(hex) = self.load_hex()? else {
            return Ok(None);
        };
        Ok(Some(MasterKey::from_hex(&hex).context(self.source())?))
    }

    /// The key's text, zeroed when dropped.
    pub fn load_hex(&self) -> anyhow::Result<Option<Zeroizing<String>>> {
        if let Some(path) = &self.key_file {
            return read_key_file(path).map(Some);
        }
        Ok(std::env::var("SWEEPER_FLEET_KEY").ok().map(Zeroizing::new))
    }

    fn source(&self) -> String {
        match &self.key_file {
            Some(path) => format!("key file {}", path.display()),
            None => "SWEEPER_FLEET_KEY".into(),
        }
    }
}

/// The fleet's master key, or the one error every command that needs it gives.
pub fn require_key(key: &KeyArgs) -> anyhow::Result<MasterKey> {
    key.load()?.ok_or_else(|| {
        anyhow::anyhow!(
            "no fleet key: pass --key-file FILE or set SWEEPER_KEY_FILE or SWEEPER_FLEET_KEY \
             (64 hex digits; make one with  (umask 077; openssl rand -hex 32 > fleet.key))"
        )
    })
}

/// Largest key file read: a key is 64 hex digits and a newline.
const MAX_KEY_FILE: u64 = 1024;

/// Reads a key file as ssh reads a private key: only if nobody but its owner can read it,
/// and only if it is small enough to be one.
pub fn read_key_file(path: &Path) -> anyhow::Result<Zeroizing<String>> {
    use std::os::unix::fs::PermissionsExt;
    let meta = std::fs::metadata(path)
        .with_context(|| format!("cannot read the key file {}", path.display()))?;
    if !meta.is_file() || meta.len() > MAX_KEY_FILE {
        bail!(
            "{} is not a key file ({} bytes; a key is 64 hex digits)",
            path.display(),
            meta.len()
        );
    }
    let mode = meta.permissions().mode() & 0o777;
    if mode & 0o077 != 0 {
        bail!(
            "the key file {} can be read by others (mode {mode:03o}): run  chmod 600 {}",
            path.display(),
            path.display()
        );
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the key file {}", path.display()))?;
    Ok(Zeroizing::new(text))
}
