//! `kerfmeter serve`: the Kerfmeter server (WebSocket JSON-RPC and HTTP JSON, with a page);
//! see [`crate::serve`] for the API and the security rules. This module holds its flags.

use std::net::SocketAddr;

use clap::Args;
use kerfmeter::grbl::CutterAddress;

use super::Done;
use crate::connection::Global;
use crate::error::CliError;
use crate::serve::{Cutter, Security, serve};

/// `kerfmeter serve`'s flags.
#[derive(Args)]
pub struct ServeArgs {
    /// Address and port to listen on (port 0: any free one, printed at startup). Any address
    /// but loopback needs --token.
    #[arg(long, default_value = "127.0.0.1:7878", value_name = "IP:PORT", value_parser = listen_address)]
    listen: SocketAddr,
    /// Secret that clients must send (`Authorization: Bearer TOKEN`, or `?token=TOKEN`):
    /// letters, digits and - . _ ~. Also from KERFMETER_TOKEN.
    #[arg(long, env = "KERFMETER_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// Also accept WebSocket connections and POSTs from pages of this origin
    /// (e.g. http://localhost:5173); repeatable.
    #[arg(long = "allow-origin", value_name = "ORIGIN")]
    allow_origins: Vec<String>,
    /// The laser cutter `job` runs on: `sim` or `ruida-sim` (with --sim), `grbl:/dev/ttyUSB0`,
    /// `grbl+tcp://HOST:PORT` or `ruida:HOST?z-mm=MIN,MAX`. Without it, `job` is refused.
    #[arg(long, value_name = "ADDRESS", value_parser = cutter_address)]
    cutter: Option<String>,
    /// Let a client's `job` clear the cutter's alarm (`unlock`). An alarm is the controller's
    /// own stop (a limit switch, a door, a reset mid-job): by default only someone at the
    /// machine clears it (`kerfmeter job --unlock`).
    #[arg(long, requires = "cutter")]
    allow_unlock: bool,
}

/// `--listen`: an IP address and port; `localhost:PORT` is IPv4 loopback. Other names are not
/// looked up: a name that resolves to a network interface would open the server to that
/// network without the user having typed an address.
fn listen_address(text: &str) -> Result<SocketAddr, String> {
    if let Ok(address) = text.parse() {
        return Ok(address);
    }
    if let Some(port) = text.strip_prefix("localhost:") {
        return port
            .parse::<u16>()
            .map(|port| SocketAddr::from(([127, 0, 0, 1], port)))
            .map_err(|_| format!("`{port}` is not a port (0 to 65535)"));
    }
    Err(
        "give an IP address and a port, such as 127.0.0.1:7878 (this machine only), \
         localhost:7878, or 0.0.0.0:7878 (every network, needs --token); other host names are \
         not looked up"
            .into(),
    )
}

/// A cutter address, checked as `kerfmeter job` checks it.
fn cutter_address(text: &str) -> Result<String, String> {
    text.parse::<CutterAddress>()
        .map(|_| text.to_owned())
        .map_err(|e| e.to_string())
}

/// Serve until Ctrl-C.
pub fn run(g: &Global, args: &ServeArgs) -> Result<Done, CliError> {
    // Every measurement the server makes is recorded: a mistyped --db is said now.
    g.check_db_folder()?;
    let security = Security::new(args.listen, args.token.clone(), &args.allow_origins)?;
    let cutter = args.cutter.clone().map(|address| Cutter {
        address,
        allow_unlock: args.allow_unlock,
    });
    serve(g, args.listen, security, cutter)?;
    Ok(Done::new("server stopped; the motor is stopped"))
}
