//! The robot server: the simulated cell ([`cell`]) behind a TCP socket speaking protocol v1
//! ([`crate::protocol`], `docs/PROTOCOL.md`).
//!
//! One tokio task per connection reads newline-ended lines (tokio-util's length-limited
//! delimiter codec: a line over 1 MiB is `too_large` and the connection closes), answers each
//! with one line, and hands what needs the cell to the cell's own thread, which owns the
//! physics and serves one job at a time. `status` is answered from a snapshot the cell publishes
//! after every job, so it never waits behind a motion. A second motion while one runs is
//! `busy`; so is a ninth connection. Idle connections close after 30 s. Off loopback a token is
//! required, compared in constant time. Nothing a peer sends can panic the server or move the
//! arm unless it is a valid motion request.

pub mod cell;
pub mod judge;
pub mod pick;

use crate::protocol::{
    ErrorCode, IDLE_TIMEOUT_S, MAX_CONNECTIONS, MAX_LINE_BYTES, PROTOCOL, Request, StatusReply, TruthReply, WireError,
    parse_request, reply_line,
};
use anyhow::{Context, bail};
use futures_util::{SinkExt, StreamExt};
use serde_json::Value;
use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Notify, oneshot};
use tokio_util::codec::{AnyDelimiterCodec, AnyDelimiterCodecError, Framed};

pub use cell::CellConfig;

/// How to run the server.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    pub cell: CellConfig,
    pub listen: SocketAddr,
    /// Required of every connection (in `hello`) when set; required to listen off loopback.
    pub token: Option<String>,
    pub idle_timeout: Duration,
    /// Stop on Ctrl-C (the `serve` command; not when a run starts the server in-process).
    pub stop_on_ctrl_c: bool,
}

impl ServerConfig {
    pub fn new(cell: CellConfig, listen: SocketAddr) -> ServerConfig {
        ServerConfig {
            cell,
            listen,
            token: None,
            idle_timeout: Duration::from_secs_f64(IDLE_TIMEOUT_S),
            stop_on_ctrl_c: false,
        }
    }
}

/// A job for the cell's thread, with where its reply goes.
pub(crate) struct CellJob {
    pub request: Request,
    pub reply: oneshot::Sender<Result<Value, WireError>>,
    /// Asked by the process that started the server ([`Server::truth`]), not by a peer: the
    /// `truth` op is answered to it whether or not the socket serves it.
    pub in_process: bool,
}

/// What the cell and the connections share.
pub(crate) struct Shared {
    /// A motion (move, pick, home) is running.
    pub moving: AtomicBool,
    /// The cell's state after its last job.
    pub status: Mutex<StatusReply>,
}

/// What the connections share (the cell holds none of it: once the last of it is gone, the
/// cell's queue closes and its thread ends).
struct Net {
    shared: Arc<Shared>,
    connections: AtomicUsize,
    token: Option<String>,
    idle_timeout: Duration,
    jobs: Mutex<std::sync::mpsc::Sender<CellJob>>,
    stop: Notify,
}

/// A running server.
pub struct Server {
    addr: SocketAddr,
    net: Arc<Net>,
    network: std::thread::JoinHandle<()>,
    cell: std::thread::JoinHandle<()>,
}

impl Server {
    /// Loads and settles the cell, binds the listener, and serves in the background.
    pub fn start(config: ServerConfig) -> anyhow::Result<Server> {
        if !config.listen.ip().is_loopback() && config.token.as_deref().is_none_or(str::is_empty) {
            bail!(
                "refusing to listen on {} without a token: off loopback anyone could move the arm; give --token-file F or set MARVIN_TOKEN",
                config.listen
            );
        }
        let (jobs_tx, jobs_rx) = std::sync::mpsc::channel();
        let shared = Arc::new(Shared {
            moving: AtomicBool::new(false),
            status: Mutex::new(StatusReply {
                joints: BTreeMap::new(),
                gripper_opening_mm: 0.0,
                holding: None,
                calibrated: false,
                sim_time_s: 0.0,
                moving: false,
            }),
        });
        let net = Arc::new(Net {
            shared: shared.clone(),
            connections: AtomicUsize::new(0),
            token: config.token.clone(),
            idle_timeout: config.idle_timeout,
            jobs: Mutex::new(jobs_tx),
            stop: Notify::new(),
        });
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let cell = {
            let (cfg, shared) = (config.cell.clone(), shared.clone());
            std::thread::Builder::new()
                .name("marvin-cell".into())
                .spawn(move || cell::run(cfg, jobs_rx, shared, ready_tx))
                .context("starting the cell's thread")?
        };
        ready_rx.recv().context("the cell's thread ended before it was ready")??;
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(2)
            .thread_name("marvin-net")
            .enable_all()
            .build()
            .context("starting the network runtime")?;
        let listener = runtime
            .block_on(TcpListener::bind(config.listen))
            .with_context(|| format!("cannot listen on {}", config.listen))?;
        let addr = listener.local_addr()?;
        let network = {
            let net = net.clone();
            std::thread::Builder::new()
                .name("marvin-accept".into())
                .spawn(move || runtime.block_on(accept_loop(listener, net, config.stop_on_ctrl_c)))
                .context("starting the network thread")?
        };
        tracing::info!(%addr, "robot server listening");
        Ok(Server { addr, net, network, cell })
    }

    /// The address it listens on (the port chosen, for `--listen 127.0.0.1:0`).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The simulation's truth, asked in-process by the code that started the server (evaluation
    /// judging a run after the fact): it never travels over the socket, which answers the
    /// `truth` op only when the server was started with `--truth`. Waits behind a running job.
    pub fn truth(&self) -> anyhow::Result<TruthReply> {
        let (tx, rx) = oneshot::channel();
        let job = CellJob { request: Request::Truth {}, reply: tx, in_process: true };
        let sent = self.net.jobs.lock().unwrap_or_else(|e| e.into_inner()).send(job);
        sent.map_err(|_| anyhow::anyhow!("the cell has stopped"))?;
        let value = rx
            .blocking_recv()
            .context("the cell dropped the truth request")?
            .map_err(|e| anyhow::anyhow!("truth: {e}"))?;
        serde_json::from_value(value).context("the cell's truth")
    }

    /// Asks the server to stop (as an authorised `shutdown` does).
    pub fn stop(&self) {
        self.net.stop.notify_one();
    }

    /// Waits until the server has stopped, and the cell's thread with it.
    pub fn wait(self) -> anyhow::Result<()> {
        self.network.join().map_err(|_| anyhow::anyhow!("the network thread panicked"))?;
        // The cell's thread ends once the last sender of jobs is gone.
        drop(self.net);
        self.cell.join().map_err(|_| anyhow::anyhow!("the cell's thread panicked"))?;
        Ok(())
    }
}

async fn accept_loop(listener: TcpListener, net: Arc<Net>, stop_on_ctrl_c: bool) {
    let ctrl_c = async {
        if stop_on_ctrl_c {
            let _ = tokio::signal::ctrl_c().await;
        } else {
            std::future::pending::<()>().await;
        }
    };
    tokio::pin!(ctrl_c);
    loop {
        tokio::select! {
            accepted = listener.accept() => match accepted {
                Ok((stream, peer)) => {
                    let _ = stream.set_nodelay(true);
                    let net = net.clone();
                    tokio::spawn(async move { serve_connection(stream, peer, net).await });
                }
                Err(e) => tracing::warn!("accept failed: {e}"),
            },
            _ = net.stop.notified() => break,
            _ = &mut ctrl_c => break,
        }
    }
    tracing::info!("robot server stopping");
}

/// Counts a connection while it lives.
struct ConnectionSlot(Arc<Net>);

impl Drop for ConnectionSlot {
    fn drop(&mut self) {
        self.0.connections.fetch_sub(1, Ordering::SeqCst);
    }
}

type Lines = Framed<TcpStream, AnyDelimiterCodec>;

async fn send(lines: &mut Lines, id: &Value, result: &Result<Value, WireError>) -> bool {
    lines.send(reply_line(id, result)).await.is_ok()
}

async fn serve_connection(stream: TcpStream, peer: SocketAddr, shared: Arc<Net>) {
    let codec = AnyDelimiterCodec::new_with_max_length(b"\n".to_vec(), b"\n".to_vec(), MAX_LINE_BYTES);
    let mut lines = Framed::new(stream, codec);
    let count = shared.connections.fetch_add(1, Ordering::SeqCst) + 1;
    let _slot = ConnectionSlot(shared.clone());
    if count > MAX_CONNECTIONS {
        tracing::warn!(%peer, "refused: {MAX_CONNECTIONS} connections already");
        let busy = WireError::new(ErrorCode::Busy, format!("the server serves {MAX_CONNECTIONS} connections at most"));
        send(&mut lines, &Value::Null, &Err(busy)).await;
        close_gracefully(lines).await;
        return;
    }
    tracing::info!(%peer, "connected");
    let mut authorised = shared.token.is_none();
    loop {
        let line = match tokio::time::timeout(shared.idle_timeout, lines.next()).await {
            Err(_) => {
                tracing::info!(%peer, "idle for {:?}; closing", shared.idle_timeout);
                break;
            }
            Ok(None) => break,
            Ok(Some(Err(AnyDelimiterCodecError::MaxChunkLengthExceeded))) => {
                let e =
                    WireError::new(ErrorCode::TooLarge, format!("a request line is at most {MAX_LINE_BYTES} bytes"));
                tracing::warn!(%peer, "too large; closing");
                send(&mut lines, &Value::Null, &Err(e)).await;
                close_gracefully(lines).await;
                return;
            }
            Ok(Some(Err(e))) => {
                tracing::warn!(%peer, "read failed: {e}");
                break;
            }
            Ok(Some(Ok(bytes))) => bytes,
        };
        let line = line.strip_suffix(b"\r").unwrap_or(&line);
        if line.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let t0 = Instant::now();
        let (id, parsed) = parse_request(line);
        let op = parsed.as_ref().map(|r| r.op()).unwrap_or("?");
        let (result, close) = match parsed {
            Err(e) => (Err(e), false),
            Ok(request) => handle(request, &shared, &mut authorised).await,
        };
        let code = result.as_ref().err().map(|e| e.code.as_str()).unwrap_or("ok");
        tracing::info!(%peer, %id, op, code, ms = t0.elapsed().as_secs_f64() * 1e3, "request");
        if !send(&mut lines, &id, &result).await {
            break;
        }
        if close {
            close_gracefully(lines).await;
            break;
        }
    }
    tracing::info!(%peer, "closed");
}

/// Closes after a last reply so that the peer reads it: our side is shut for writing, and what
/// the peer still sends is read and dropped for a moment. (Closed at once with its bytes
/// unread, the socket would be reset, and a reset can discard the reply before it is read.)
async fn close_gracefully(lines: Lines) {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut stream = lines.into_inner();
    let _ = stream.shutdown().await;
    let mut sink = [0u8; 16 * 1024];
    let drain = async {
        let mut total = 0usize;
        while total < 4 * MAX_LINE_BYTES {
            match stream.read(&mut sink).await {
                Ok(0) | Err(_) => break,
                Ok(n) => total += n,
            }
        }
    };
    let _ = tokio::time::timeout(Duration::from_secs(1), drain).await;
}

/// One request's reply, and whether the connection closes after it.
async fn handle(request: Request, net: &Net, authorised: &mut bool) -> (Result<Value, WireError>, bool) {
    let unauthorised = |m: &str| (Err(WireError::new(ErrorCode::Unauthorized, m)), true);
    match &request {
        Request::Hello { protocol, token } => {
            if let Some(expected) = &net.token {
                let given = token.as_deref().unwrap_or("");
                if !bool::from(subtle::ConstantTimeEq::ct_eq(given.as_bytes(), expected.as_bytes())) {
                    return unauthorised("wrong or missing token");
                }
                *authorised = true;
            }
            if *protocol != PROTOCOL {
                let e = WireError::new(
                    ErrorCode::BadRequest,
                    format!("this server speaks protocol {PROTOCOL}, not {protocol}"),
                );
                return (Err(e), false);
            }
        }
        _ if !*authorised => return unauthorised("this server needs `hello` with its token first"),
        Request::Status {} => {
            let mut status = net.shared.status.lock().unwrap_or_else(|e| e.into_inner()).clone();
            status.moving = net.shared.moving.load(Ordering::SeqCst);
            return (Ok(serde_json::to_value(status).expect("status serialises")), false);
        }
        Request::Bye {} => return (Ok(serde_json::json!({})), true),
        Request::Shutdown {} => {
            net.stop.notify_one();
            return (Ok(serde_json::json!({ "stopping": true })), true);
        }
        _ => {}
    }
    if request.is_motion()
        && net.shared.moving.compare_exchange(false, true, Ordering::SeqCst, Ordering::SeqCst).is_err()
    {
        return (Err(WireError::new(ErrorCode::Busy, "another motion is running; one at a time")), false);
    }
    (ask_cell(request, net).await, false)
}

async fn ask_cell(request: Request, net: &Net) -> Result<Value, WireError> {
    let (tx, rx) = oneshot::channel();
    let motion = request.is_motion();
    let sent =
        net.jobs.lock().unwrap_or_else(|e| e.into_inner()).send(CellJob { request, reply: tx, in_process: false });
    if sent.is_err() {
        if motion {
            net.shared.moving.store(false, Ordering::SeqCst);
        }
        return Err(WireError::new(ErrorCode::Internal, "the cell has stopped"));
    }
    rx.await.unwrap_or_else(|_| Err(WireError::new(ErrorCode::Internal, "the cell dropped the request")))
}
