//! `aeris agent`: the daemon that runs roles on this host for a flight whose supervisor runs
//! on another (`aeris-hosts`). It prints what it does until Ctrl-C, then stops its roles.

use aeris_hosts::admission::{AllowList, DEFAULT_ALLOW, OwnParam};
use aeris_hosts::agent::{Agent, AgentConfig};
use aeris_hosts::session::LinkSecurity;
use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::PathBuf;
use std::time::Duration;

/// Arguments of `aeris agent`.
#[derive(Debug, Args)]
pub struct AgentArgs {
    /// This host's name, as the workflow's `[hosts.NAME]` calls it (and its certificate).
    #[arg(long)]
    pub host: String,
    /// zenoh endpoint to listen on (the workflow's `endpoint` for this host), repeatable.
    /// `tls/` needs --keys; `tcp/` needs --insecure.
    #[arg(
        long,
        value_name = "tls/ADDRESS:PORT",
        default_value = "tls/0.0.0.0:7447"
    )]
    pub listen: Vec<String>,
    /// This host's identity: the directory `aeris keys issue STORE HOST` made for it (the
    /// flight's CA, this host's certificate and key). Every link is then mutual TLS, and
    /// only certificates of that CA get in.
    #[arg(long, value_name = "DIR")]
    pub keys: Option<PathBuf>,
    /// The certificate name of a host whose supervisor may start and stop roles here
    /// (repeatable; required with --keys).
    #[arg(long = "flight-host", value_name = "NAME")]
    pub flight_hosts: Vec<String>,
    /// Listen on plain TCP: no authentication, no encryption, anyone who reaches the port
    /// may start the allowed roles here. Only for a closed test network.
    #[arg(long, conflicts_with = "keys")]
    pub insecure: bool,
    /// The role kinds and variants this agent starts (KIND/VARIANT or KIND/*,
    /// comma-separated or repeated; the bridge always). Default: the model and reasoning
    /// roles.
    #[arg(long, value_name = "KIND/VARIANT,...")]
    pub allow: Vec<String>,
    /// A parameter this agent sets itself for the roles of a kind, such as a model file
    /// (`reasoning/smollm2.model=/opt/models/smollm2.gguf`): what names a file, model,
    /// pipeline or endpoint never comes from the network. Repeatable.
    #[arg(long = "param", value_name = "KIND[/VARIANT].KEY=VALUE")]
    pub params: Vec<String>,
    /// Where role specs and logs go (default: $TMPDIR/aeris-agent-UID/HOST): a private
    /// directory, refused if another user owns any part of it or it is reached by a link.
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
    let security = match (&args.keys, args.insecure) {
        (Some(dir), _) => LinkSecurity::Tls(
            aeris_hosts::keys::Identity::load(dir).context("loading this host's keys (--keys)")?,
        ),
        (None, true) => LinkSecurity::Insecure,
        (None, false) => bail!(
            "the agent needs this host's keys (--keys DIR): make a flight CA with `aeris keys init STORE`, \
             this host's identity with `aeris keys issue STORE {} --address ADDRESS`, and copy STORE/{} here \
             (or --insecure on a closed test network)",
            args.host,
            args.host
        ),
    };
    let allow = if args.allow.is_empty() {
        AllowList::parse(DEFAULT_ALLOW)
    } else {
        AllowList::parse(&args.allow)
    }
    .context("reading --allow")?;
    let own_params = args
        .params
        .iter()
        .map(|p| OwnParam::parse(p))
        .collect::<Result<Vec<_>, _>>()
        .context("reading --param")?;
    // per user: another user's agent (or a squatter) never shares it
    let uid = aeris_hosts::private_dir::current_uid();
    let run_dir = args.run_dir.unwrap_or_else(|| {
        std::env::temp_dir()
            .join(format!("aeris-agent-{uid}"))
            .join(&args.host)
    });
    let exe = std::env::current_exe().context("locating the aeris executable")?;
    let identity = match &security {
        LinkSecurity::Tls(id) => Some((id.name.clone(), id.not_after.clone())),
        LinkSecurity::Insecure => None,
    };
    let config = AgentConfig {
        host: args.host.clone(),
        listen: args.listen.clone(),
        run_dir,
        exe,
        lease: Duration::from_millis(args.link_timeout_ms),
        security,
        flight_hosts: args.flight_hosts.clone(),
        allow,
        own_params,
    };
    let mut agent = Agent::start(config)
        .with_context(|| format!("starting the agent of host `{}`", args.host))?;
    match identity {
        Some((name, until)) => println!(
            "agent of host `{}`: mutual TLS as `{name}` (certificate valid until {until}); \
             roles started by: {}",
            args.host,
            args.flight_hosts.join(", ")
        ),
        None => eprintln!(
            "agent of host `{}`: INSECURE: plain TCP, no authentication, no encryption: \
             anyone who reaches {} may start roles here and read and write the flights' data",
            args.host,
            args.listen.join(", ")
        ),
    }
    println!(
        "agent of host `{}` listening on {} ({}; runs {}; roles' logs in {})",
        args.host,
        args.listen.join(", "),
        aeris_hosts::protocol::SchemaStamp::current(),
        agent.allow_list(),
        agent.run_dir().display()
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

impl crate::command::Execute for AgentArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
