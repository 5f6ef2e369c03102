//! The fleet's bus: Zenoh, between the stations of a city's formations and the operations
//! view. [`keys`]: the key space; [`payload`]: what each key carries (JSON);
//! [`station`]: a station on the bus (`run|sim … --zenoh`); [`ops`]: `basestation ops`,
//! every formation on one page. Each side reads Zenoh's own JSON5 configuration file, so
//! routers, access control and authentication are configured as for any Zenoh system
//! (docs/operating.md#a-citys-fleet-on-zenoh).

pub mod keys;
pub mod ops;
pub mod payload;
pub mod station;

use std::path::Path;

/// Zenoh's configuration from `path` (JSON5, as `zenohd -c` reads it), with the file named
/// in any error.
pub fn load_config(path: &Path) -> anyhow::Result<zenoh::Config> {
    if !path.is_file() {
        anyhow::bail!("--zenoh {}: no such file", path.display());
    }
    zenoh::Config::from_file(path).map_err(|e| anyhow::anyhow!("--zenoh {}: {e}", path.display()))
}
