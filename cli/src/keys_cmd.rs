//! `aeris keys`: the flight's certificate authority and its hosts' identities
//! (`aeris_hosts::keys`).

use aeris_hosts::keys::{DEFAULT_CA_DAYS, DEFAULT_HOST_DAYS};
use anyhow::{Context, Result};
use clap::Subcommand;
use std::path::PathBuf;

/// Arguments of `aeris keys`.
#[derive(Debug, clap::Args)]
pub struct KeysArgs {
    #[command(subcommand)]
    command: KeysCommand,
}

/// `aeris keys` subcommands.
#[derive(Debug, Subcommand)]
pub enum KeysCommand {
    /// Make a flight CA in STORE (created owner-only): STORE/ca.pem and STORE/ca.key. Keep
    /// ca.key on the machine that makes keys; it never goes to a vehicle.
    Init {
        /// The key store (a directory).
        store: PathBuf,
        /// Days the CA is valid.
        #[arg(long, default_value_t = DEFAULT_CA_DAYS)]
        days: u32,
    },
    /// Issue HOST an identity from STORE's CA: STORE/HOST/ (ca.pem, cert.pem, key.pem), to
    /// copy to that host and give as `aeris agent --keys` there, or as a workflow's
    /// `[hosts.NAME] keys` on the flight's host.
    Issue {
        /// The key store.
        store: PathBuf,
        /// The host's name (the certificate's common name; what access rules name).
        host: String,
        /// An address or DNS name the host is reached at (its agent's endpoint address),
        /// repeatable; the host name and the loopback addresses are always in.
        #[arg(long = "address", value_name = "ADDRESS")]
        addresses: Vec<String>,
        /// Days the certificate is valid: short-lived, so a lost key stops working soon
        /// (re-issue with --replace to rotate).
        #[arg(long, default_value_t = DEFAULT_HOST_DAYS)]
        days: u32,
        /// Replace the host's existing identity (a new key and certificate).
        #[arg(long)]
        replace: bool,
    },
    /// Check an identity directory: its name, its CA, until when it holds.
    Show {
        /// An identity directory (STORE/HOST).
        dir: PathBuf,
    },
}

/// `aeris keys`.
pub fn run(command: KeysCommand) -> Result<()> {
    match command {
        KeysCommand::Init { store, days } => {
            let made = aeris_hosts::keys::init(&store, days).context("making a flight CA")?;
            println!("flight CA valid until {}", made.not_after);
            println!("  certificate: {}", made.cert.display());
            println!(
                "  private key: {} (0600: keep it here, never on a vehicle)",
                made.key.display()
            );
            println!(
                "next: aeris keys issue {} HOST --address ADDRESS, for every host",
                store.display()
            );
        }
        KeysCommand::Issue {
            store,
            host,
            addresses,
            days,
            replace,
        } => {
            let issued = aeris_hosts::keys::issue(&store, &host, &addresses, days, replace)
                .context("issuing a host identity")?;
            println!(
                "host `{host}`: certificate valid until {} for {}",
                issued.not_after,
                issued.names.join(", ")
            );
            println!("  {} (the flight's CA)", issued.ca.display());
            println!("  {}", issued.cert.display());
            println!("  {} (0600)", issued.key.display());
            println!(
                "copy {} to host `{host}` (its `aeris agent --keys`, or a workflow's `[hosts.*] keys` on the flight's host)",
                issued.dir.display()
            );
        }
        KeysCommand::Show { dir } => {
            let id = aeris_hosts::keys::Identity::load(&dir).context("checking a host identity")?;
            println!(
                "host `{}`: signed by the CA in {}, valid until {} ({} days left)",
                id.name,
                id.ca.display(),
                id.not_after,
                id.expires_in_s / 86_400
            );
        }
    }
    Ok(())
}

impl crate::command::Execute for KeysArgs {
    fn execute(self) -> anyhow::Result<std::process::ExitCode> {
        run(self.command)?;
        Ok(std::process::ExitCode::SUCCESS)
    }
}
