//! `aeris agent`: the daemon that runs roles on this host for a flight whose supervisor runs
//! on another (`aeris-hosts`). It prints what it does until Ctrl-C, then stops its roles.

use aeris_hosts::agent::{Agent, AgentConfig};
use anyhow::{Context, Result};
use clap::Args;
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `aeris agent`.
#[derive(Debug, Args)]
pub struct AgentArgs {
    /// This host's name, as the workflow's `[hosts.NAME]` calls it.
    #[arg(long)]
    pub host: String,
    /// zenoh endpoint to listen on (the workflow's `endpoint` for this host), repeatable.
    #[arg(
        long,
        value_name = "tcp/ADDRESS:PORT",
        default_value = "tcp/0.0.0.0:7447"
    )]
    pub listen: Vec<String>,
    /// Where role specs and logs go (default: $TMPDIR/aeris-agent/HOST).
    #[arg(long, value_name = "DIR")]
    pub run_dir: Option<PathBuf>,
    /// A flight's host silent this long is gone and its roles here are stopped (ms).
    #[arg(long, value_name = "MS", default_value_t = 1000)]
    pub link_timeout_ms: u64,
}

/// How often the agent answers requests and reaps its roles.
const STEP: Duration = Duration::from_millis(5);

/// `aeris agent`.
pub fn run(args: AgentArgs) -> Result<()> {
    aeris_runtime::signals::install_termination_handlers()
        .context("installing the signal handlers")?;
    let run_dir = args
        .run_dir
        .unwrap_or_else(|| std::env::temp_dir().join("aeris-agent").join(&args.host));
    let exe = std::env::current_exe().context("locating the aeris executable")?;
    let config = AgentConfig {
        host: args.host.clone(),
        listen: args.listen.clone(),
        run_dir: run_dir.clone(),
        exe,
        lease: Duration::from_millis(args.link_timeout_ms),
    };
    let mut agent = Agent::start(config)
        .with_context(|| format!("starting the agent of host `{}`", args.host))?;
    println!(
        "agent of host `{}` listening on {} ({}; roles' logs in {})",
        args.host,
        args.listen.join(", "),
        aeris_hosts::protocol::SchemaStamp::current(),
        run_dir.display()
    );
    println!(
        "roles' priority over this host's other work: {}",
        agent.priority()
    );
    while !aeris_runtime::signals::termination_requested() {
        for e in agent.step() {
            println!("{e}");
        }
        std::thread::sleep(STEP);
    }
    println!(
        "agent of host `{}` stopping {} role(s)",
        args.host,
        agent.running()
    );
    for e in agent.shutdown() {
        println!("{e}");
    }
    Ok(())
}
