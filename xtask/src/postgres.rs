//! A real PostgreSQL server for the history's tests and benchmark (issue 36): the step "history
//! against PostgreSQL" of `cargo xtask test`, `cargo xtask test-history-pg` alone, and `cargo
//! xtask bench-history`.
//!
//! The server is Debian's (`/usr/lib/postgresql/VERSION/bin`, the newest there; or `initdb` on
//! the `PATH`), installed with `apt-get install postgresql` when missing and this runs as root;
//! otherwise the step fails with the command to run. Each run makes a cluster of its own in a
//! temporary folder (`initdb`, trust authentication), starts it on a free loopback port
//! (`listen_addresses = 127.0.0.1`, its Unix socket in the same folder, so nothing of the
//! machine's own PostgreSQL is touched), creates a database, and hands its URL to the tests in
//! [`URL_VAR`]. The server never runs as root: when this does, the cluster belongs to, and runs
//! as, the `postgres` user the package made (or `nobody`), through `runuser`. [`Server`]'s drop
//! stops it and removes the folder, whether the tests passed or not.

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result, bail};

use crate::browser::is_root;
use crate::{cargo, run_cmd};

/// The environment variable that gives the tests the server's URL; the history's PostgreSQL
/// tests fail when it is missing.
pub const URL_VAR: &str = "KERFMETER_TEST_PG_URL";
/// The environment variable that gives the restart test the server's `pg_ctl` command line, one
/// argument a line, to which it adds `stop` or `start`.
pub const CTL_VAR: &str = "KERFMETER_TEST_PG_CTL";
/// The folder Debian installs each PostgreSQL version's programs under.
const DEBIAN_LIB: &str = "/usr/lib/postgresql";
/// The role and database the tests use.
const ROLE: &str = "kerfmeter";
const DATABASE: &str = "kerfmeter_test";
/// Unprivileged users the server may run as when this runs as root, in order of preference.
const SERVER_USERS: [&str; 2] = ["postgres", "nobody"];

/// A PostgreSQL server running for the tests; stopped, and its folder removed, when dropped.
pub struct Server {
    bin: PathBuf,
    dir: PathBuf,
    /// The unprivileged user it runs as (when this runs as root).
    user: Option<String>,
    /// `postgres://kerfmeter@127.0.0.1:PORT/kerfmeter_test`.
    pub url: String,
}

impl Server {
    /// Find or install PostgreSQL, make a cluster in a temporary folder and start it.
    pub fn start() -> Result<Server> {
        let bin = ensure_installed()?;
        let user = if is_root() {
            Some(
                SERVER_USERS
                    .iter()
                    .find(|u| user_exists(u))
                    .context("running as root, but no unprivileged user (postgres, nobody) to run the server as")?
                    .to_string(),
            )
        } else {
            None
        };
        let stamp = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_nanos());
        // The server's user must reach the folder: as root, /tmp (open to all) rather than a
        // TMPDIR that may be root's own.
        let base = if user.is_some() {
            PathBuf::from("/tmp")
        } else {
            std::env::temp_dir()
        };
        let dir = base.join(format!("kerfmeter-pg-{}-{stamp}", std::process::id()));
        std::fs::create_dir(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let port = free_port()?;
        let url = format!("postgres://{ROLE}@127.0.0.1:{port}/{DATABASE}");
        // From here on, dropping `server` stops what was started and removes the folder.
        let server = Server {
            bin,
            dir,
            user,
            url,
        };
        if let Some(user) = &server.user {
            run_cmd(
                Command::new("chown")
                    .arg(format!("{user}:"))
                    .arg(&server.dir),
            )?;
        }
        let data = server.dir.join("data");
        run_cmd(server.as_server_user("initdb").arg("-D").arg(&data).args([
            "-U",
            ROLE,
            "--auth=trust",
            "-E",
            "UTF8",
            "--no-locale",
            "--no-sync",
        ]))
        .context("initdb failed")?;
        // In its configuration rather than on pg_ctl's command line, so that a test that stops
        // and starts it again ([`CTL_VAR`]) starts the same server.
        let settings = format!(
            "\n# cargo xtask: loopback only, its socket in its own folder\n\
             listen_addresses = '127.0.0.1'\nport = {port}\nunix_socket_directories = '{}'\n",
            server.dir.display()
        );
        std::fs::OpenOptions::new()
            .append(true)
            .open(data.join("postgresql.conf"))
            .and_then(|mut f| std::io::Write::write_all(&mut f, settings.as_bytes()))
            .context("cannot configure the test server")?;
        run_cmd(server.pg_ctl().args(["-w", "-t", "60", "start"]))
            .with_context(|| server.log_tail("the server did not start"))?;
        run_cmd(
            Command::new(server.bin.join("createdb"))
                .args([
                    "-h",
                    "127.0.0.1",
                    "-p",
                    &port.to_string(),
                    "-U",
                    ROLE,
                    DATABASE,
                ])
                .env_remove("PGPASSWORD"),
        )?;
        eprintln!("PostgreSQL running for the tests: {}", server.url);
        Ok(server)
    }

    /// `program` from the server's folder, as the unprivileged user when this runs as root.
    fn as_server_user(&self, program: &str) -> Command {
        let path = self.bin.join(program);
        match &self.user {
            Some(user) => {
                let mut cmd = Command::new("runuser");
                cmd.args(["-u", user, "--"]).arg(path);
                cmd
            }
            None => Command::new(path),
        }
    }

    /// `pg_ctl` on this server's cluster, logging to its log, as the server's user.
    fn pg_ctl(&self) -> Command {
        let mut cmd = self.as_server_user("pg_ctl");
        cmd.arg("-D")
            .arg(self.dir.join("data"))
            .arg("-l")
            .arg(self.dir.join("server.log"));
        cmd
    }

    /// The `pg_ctl` command line ([`Server::pg_ctl`]) as [`CTL_VAR`] gives it: one argument a line.
    pub fn ctl_var(&self) -> String {
        let cmd = self.pg_ctl();
        std::iter::once(cmd.get_program())
            .chain(cmd.get_args())
            .map(|a| a.to_string_lossy().into_owned())
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// `what`, with the end of the server's log.
    fn log_tail(&self, what: &str) -> String {
        let log = std::fs::read_to_string(self.dir.join("server.log")).unwrap_or_default();
        let tail: Vec<&str> = log.lines().rev().take(20).collect();
        let tail: Vec<&str> = tail.into_iter().rev().collect();
        format!("{what}; its log ends:\n{}", tail.join("\n"))
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let data = self.dir.join("data");
        if data.join("postmaster.pid").exists() {
            let stopped = self.pg_ctl().args(["-m", "fast", "-w", "stop"]).status();
            if !stopped.is_ok_and(|s| s.success()) {
                eprintln!(
                    "warning: could not stop the test PostgreSQL in {}",
                    self.dir.display()
                );
            }
        }
        if let Err(e) = std::fs::remove_dir_all(&self.dir) {
            eprintln!("warning: could not remove {}: {e}", self.dir.display());
        }
    }
}

/// The folder holding `initdb`, `pg_ctl`, `postgres` and `createdb`: Debian's newest, or the
/// `PATH`'s; installed when missing and possible.
fn ensure_installed() -> Result<PathBuf> {
    if let Some(bin) = find_bin() {
        return Ok(bin);
    }
    let install = "apt-get update && apt-get install -y --no-install-recommends postgresql";
    if !is_root() || !Path::new("/usr/bin/apt-get").exists() {
        bail!(
            "the history's PostgreSQL tests need a PostgreSQL server's programs (initdb, pg_ctl, \
             postgres); install them as root: {install}"
        );
    }
    eprintln!("PostgreSQL is missing: installing Debian's postgresql with apt-get");
    let apt_install = || {
        run_cmd(
            Command::new("apt-get")
                .args(["install", "-y", "--no-install-recommends", "postgresql"])
                .env("DEBIAN_FRONTEND", "noninteractive"),
        )
    };
    // A fresh machine may have no package lists yet: update them only when the install fails.
    if apt_install().is_err() {
        run_cmd(Command::new("apt-get").arg("update"))?;
        apt_install().with_context(|| format!("could not install PostgreSQL; run: {install}"))?;
    }
    find_bin().with_context(|| {
        format!("PostgreSQL's programs are still not found after installing; run: {install}")
    })
}

fn has_programs(dir: &Path) -> bool {
    ["initdb", "pg_ctl", "postgres", "createdb"]
        .iter()
        .all(|p| dir.join(p).is_file())
}

fn find_bin() -> Option<PathBuf> {
    let mut debian: Vec<(u32, PathBuf)> = std::fs::read_dir(DEBIAN_LIB)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let version = e.file_name().to_str()?.parse().ok()?;
            Some((version, e.path().join("bin")))
        })
        .filter(|(_, bin)| has_programs(bin))
        .collect();
    debian.sort();
    if let Some((_, bin)) = debian.pop() {
        return Some(bin);
    }
    std::env::split_paths(&std::env::var_os("PATH")?).find(|dir| has_programs(dir))
}

fn user_exists(user: &str) -> bool {
    Command::new("id")
        .arg("-u")
        .arg(user)
        .output()
        .is_ok_and(|o| o.status.success())
}

/// A loopback port nothing listens on now.
fn free_port() -> Result<u16> {
    let listener = TcpListener::bind("127.0.0.1:0").context("cannot find a free port")?;
    Ok(listener.local_addr()?.port())
}

/// The history crate with its PostgreSQL back end: clippy and its docs, then its tests against a
/// server of their own (the PostgreSQL tests fail without one, never skip).
pub fn test_history() -> Result<()> {
    run_cmd(cargo().args([
        "clippy",
        "-p",
        "kerfmeter-history",
        "--features",
        "postgres",
        "--all-targets",
        "--",
        "-D",
        "warnings",
    ]))?;
    // The back end's docs, which the workspace's docs step (without the feature) does not build.
    run_cmd(
        cargo()
            .args([
                "doc",
                "-p",
                "kerfmeter-history",
                "--features",
                "postgres",
                "--no-deps",
            ])
            .env("RUSTDOCFLAGS", "-D warnings"),
    )?;
    // Built before the server starts, so that it runs only for the tests.
    run_cmd(cargo().args([
        "test",
        "-p",
        "kerfmeter-history",
        "--features",
        "postgres",
        "--no-run",
    ]))?;
    let server = Server::start()?;
    run_cmd(
        cargo()
            .args(["test", "-p", "kerfmeter-history", "--features", "postgres"])
            .env(URL_VAR, &server.url),
    )?;
    // Alone, after the others: it stops the server they use.
    run_cmd(
        cargo()
            .args(["test", "-p", "kerfmeter-history", "--features", "postgres"])
            .args(["--test", "backends", "--", "--ignored", "--exact"])
            .arg("postgres::the_server_stopped_and_started_again_keeps_every_record_once")
            .env(URL_VAR, &server.url)
            .env(CTL_VAR, server.ctl_var()),
    )
}

/// `cargo xtask bench-history`: write throughput and the time to list the newest 100 of
/// `records`, on SQLite and on a PostgreSQL server of its own.
pub fn bench_history(records: u32) -> Result<()> {
    let mut build = cargo();
    build.args([
        "build",
        "--release",
        "-p",
        "kerfmeter-history",
        "--features",
        "postgres",
        "--example",
        "bench",
    ]);
    run_cmd(&mut build)?;
    let server = Server::start()?;
    run_cmd(
        cargo()
            .args([
                "run",
                "--release",
                "-p",
                "kerfmeter-history",
                "--features",
                "postgres",
                "--example",
                "bench",
                "--",
                "--records",
                &records.to_string(),
            ])
            .env(URL_VAR, &server.url),
    )
}
