//! `basestation ops`: every formation of the bus on one page (crate::bus::ops), and
//! `basestation router`: a Zenoh router for the stations and `ops` to meet at.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Context;
use clap::Args;

use crate::bus;
use crate::live::console::server;

/// Where `ops` and `router` listen when no configuration file says.
pub const DEFAULT_BUS: &str = "tcp/127.0.0.1:7447";

#[derive(Args, Debug)]
pub struct OpsArgs {
    /// Zenoh's configuration for `ops` (JSON5, docs/operating.md#a-citys-fleet-on-zenoh).
    /// Without it, `ops` is the router itself, listening on --bus.
    #[arg(long, value_name = "CONFIG")]
    pub zenoh: Option<PathBuf>,
    /// Without --zenoh: the endpoint `ops`'s own router listens on.
    #[arg(long, value_name = "ENDPOINT", default_value = DEFAULT_BUS)]
    pub bus: String,
    /// Serve the operations page on ADDR.
    #[arg(long, value_name = "ADDR", default_value = "127.0.0.1:8090")]
    pub page: SocketAddr,
}

#[derive(Args, Debug)]
pub struct RouterArgs {
    /// Zenoh's router configuration (JSON5, as `zenohd -c` reads it). Without it, a router
    /// with no access control listening on --bus.
    #[arg(long, value_name = "CONFIG")]
    pub zenoh: Option<PathBuf>,
    /// Without --zenoh: the endpoint to listen on.
    #[arg(long, value_name = "ENDPOINT", default_value = DEFAULT_BUS)]
    pub bus: String,
}

/// `config`'s file, or a router on `endpoint` (the loopback by default: a router open to
/// the network without access control is for a file to configure, not a default).
fn config_or_router(config: Option<&PathBuf>, endpoint: &str) -> anyhow::Result<zenoh::Config> {
    if let Some(path) = config {
        return bus::load_config(path);
    }
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, key: &str, value: &str| {
        c.insert_json5(key, value)
            .map_err(|e| anyhow::anyhow!("{key}: {e}"))
    };
    set(&mut c, "mode", "\"router\"")?;
    set(&mut c, "listen/endpoints", &format!("[\"{endpoint}\"]"))?;
    set(&mut c, "scouting/multicast/enabled", "false")?;
    Ok(c)
}

/// Until Ctrl-C or SIGTERM.
fn wait_for_interrupt() -> anyhow::Result<()> {
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)).context("installing Ctrl-C")?;
    while !stop.load(Ordering::SeqCst) {
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    Ok(())
}

pub fn run(args: OpsArgs) -> anyhow::Result<()> {
    let config = config_or_router(args.zenoh.as_ref(), &args.bus)?;
    let ops = bus::ops::Ops::join(config)?;
    if args.zenoh.is_none() {
        eprintln!("ops: the bus's router is this process, on {}", args.bus);
    }
    let page = server::open("operations page", args.page, ops.backend())?;
    eprintln!("ops: {}", page.url);
    eprintln!(
        "ops: pairing code {} (open {})",
        page.shared.guard.code(),
        page.urls.join(" or ")
    );
    if let Ok(fleet) = ops.fleet.lock() {
        let known = fleet.labels();
        eprintln!(
            "ops: {} formation(s) on the bus: {}",
            known.len(),
            known.join(", ")
        );
    }
    wait_for_interrupt()
}

/// The memory storage a router keeps of the fleet's keys when its file configures none:
/// what a late `ops` reads of formations whose station has gone.
const DEFAULT_STORAGE: &str =
    r#"{ storages: { fleet: { key_expr: "sweeper/**", volume: "memory" } } }"#;

pub fn router(args: RouterArgs) -> anyhow::Result<()> {
    let mut config = config_or_router(args.zenoh.as_ref(), &args.bus)?;
    if config.get_json("plugins/storage_manager").is_err() {
        config
            .insert_json5("plugins/storage_manager", DEFAULT_STORAGE)
            .map_err(|e| anyhow::anyhow!("the default storage: {e}"))?;
    }
    // The router and its storages run on Zenoh's runtime, which needs Tokio's
    // multi-threaded scheduler.
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("cannot start the router's runtime")?;
    let router = runtime.block_on(start_router(config))?;
    eprintln!("router: up as {}", router.zid());
    wait_for_interrupt()?;
    runtime.block_on(async { router.close().await.ok() });
    Ok(())
}

/// A router with the storage manager (Zenoh's own plugin, linked in as a static plugin the
/// way `zenohd` declares its own) started from the configuration's
/// `plugins/storage_manager`.
async fn start_router(config: zenoh::Config) -> anyhow::Result<zenoh::internal::runtime::Runtime> {
    let mut plugins = zenoh::internal::plugins::PluginsManager::static_plugins_only();
    plugins.declare_static_plugin::<zenoh_plugin_storage_manager::StoragesPlugin, &str>(
        "storage_manager",
        true,
    );
    let mut runtime = zenoh::internal::runtime::RuntimeBuilder::new(config)
        .plugins_manager(plugins)
        .build()
        .await
        .map_err(|e| anyhow::anyhow!("cannot start the router: {e}"))?;
    runtime
        .start()
        .await
        .map_err(|e| anyhow::anyhow!("cannot start the router: {e}"))?;
    Ok(runtime)
}
