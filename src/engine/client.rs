//! A client of the robot server: typed requests and replies ([`crate::protocol`]) over one TCP
//! connection, one request at a time. Used by the command line and the end-to-end run.

use crate::protocol::{
    CaptureReply, HelloReply, MoveReply, MoveTarget, PROTOCOL, PickReply, PickSpec, Request, StatusReply, ToolReply,
    WireError, WirePose,
};
use serde::de::DeserializeOwned;
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

/// Why a request got no good reply.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    #[error("talking to the robot server at {addr}: {source}")]
    Io { addr: String, source: std::io::Error },
    #[error("the robot server at {addr} answered something else than protocol v1: {message}")]
    Protocol { addr: String, message: String },
    /// The server's error reply.
    #[error("the robot server refused `{op}`: {error}")]
    Server { op: &'static str, error: WireError },
}

impl ClientError {
    /// The server's error, if that is what this is.
    pub fn wire(&self) -> Option<&WireError> {
        match self {
            ClientError::Server { error, .. } => Some(error),
            _ => None,
        }
    }
}

/// One connection to a robot server.
pub struct Client {
    addr: String,
    reader: BufReader<TcpStream>,
    writer: TcpStream,
    next_id: u64,
}

/// How long a reply may take: a pick is seconds of simulation, a calibration pose less.
pub const REPLY_TIMEOUT: Duration = Duration::from_secs(300);

impl Client {
    /// Connects within `timeout` (each address `addr` resolves to, in turn).
    pub fn connect(addr: &str, timeout: Duration) -> Result<Client, ClientError> {
        let io = |source| ClientError::Io { addr: addr.to_string(), source };
        let mut last = std::io::Error::new(std::io::ErrorKind::NotFound, "the address resolves to nothing");
        for sa in addr.to_socket_addrs().map_err(io)? {
            match TcpStream::connect_timeout(&sa, timeout) {
                Ok(stream) => {
                    stream.set_nodelay(true).map_err(io)?;
                    stream.set_read_timeout(Some(REPLY_TIMEOUT)).map_err(io)?;
                    let writer = stream.try_clone().map_err(io)?;
                    return Ok(Client { addr: addr.to_string(), reader: BufReader::new(stream), writer, next_id: 1 });
                }
                Err(e) => last = e,
            }
        }
        Err(io(last))
    }

    /// Sends `request` and reads its reply, parsed as `T`.
    pub fn call<T: DeserializeOwned>(&mut self, request: &Request) -> Result<T, ClientError> {
        let id = self.next_id;
        self.next_id += 1;
        let mut line = serde_json::to_value(request).expect("requests serialise");
        line.as_object_mut().expect("a request is an object").insert("id".into(), Value::from(id));
        let io = |source| ClientError::Io { addr: self.addr.clone(), source };
        writeln!(self.writer, "{line}").map_err(io)?;
        let mut reply = String::new();
        let n =
            self.reader.read_line(&mut reply).map_err(|source| ClientError::Io { addr: self.addr.clone(), source })?;
        let protocol = |message: String| ClientError::Protocol { addr: self.addr.clone(), message };
        if n == 0 {
            return Err(protocol(format!("the connection closed before the reply to `{}`", request.op())));
        }
        let mut value: Value = serde_json::from_str(&reply).map_err(|e| protocol(format!("not JSON: {e}")))?;
        let map = value.as_object_mut().ok_or_else(|| protocol("a reply is a JSON object".into()))?;
        // An error with a null id answers the connection, not a request: `busy` when the
        // server is full, `too_large` for a line it could not read.
        let refused = map.get("id") == Some(&Value::Null) && map.get("ok") == Some(&Value::Bool(false));
        if map.get("id") != Some(&Value::from(id)) && !refused {
            return Err(protocol(format!("a reply to request {id} came with id {:?}", map.get("id"))));
        }
        match map.get("ok") {
            Some(Value::Bool(true)) => {}
            Some(Value::Bool(false)) => {
                let error = serde_json::from_value(map.remove("error").unwrap_or(Value::Null))
                    .map_err(|e| protocol(format!("an error reply without a valid `error`: {e}")))?;
                return Err(ClientError::Server { op: request.op(), error });
            }
            _ => return Err(protocol("a reply without `ok`".into())),
        }
        map.remove("id");
        map.remove("ok");
        serde_json::from_value(value).map_err(|e| protocol(format!("the reply to `{}`: {e}", request.op())))
    }

    pub fn hello(&mut self, token: Option<&str>) -> Result<HelloReply, ClientError> {
        self.call(&Request::Hello { protocol: PROTOCOL, token: token.map(str::to_string) })
    }

    pub fn status(&mut self) -> Result<StatusReply, ClientError> {
        self.call(&Request::Status {})
    }

    pub fn capture(&mut self) -> Result<CaptureReply, ClientError> {
        self.call(&Request::Capture {})
    }

    pub fn move_to(&mut self, target: MoveTarget) -> Result<MoveReply, ClientError> {
        self.call(&Request::Move(target))
    }

    pub fn set_hand_eye(&mut self, cam_from_base: WirePose) -> Result<Value, ClientError> {
        self.call(&Request::SetHandEye { cam_from_base })
    }

    pub fn pick(&mut self, spec: PickSpec) -> Result<PickReply, ClientError> {
        self.call(&Request::Pick(spec))
    }

    pub fn take_tool(&mut self, tool: &str) -> Result<ToolReply, ClientError> {
        self.call(&Request::TakeTool { tool: tool.to_string() })
    }

    pub fn stow_tool(&mut self) -> Result<ToolReply, ClientError> {
        self.call(&Request::StowTool {})
    }

    pub fn home(&mut self) -> Result<MoveReply, ClientError> {
        self.call(&Request::Home {})
    }

    pub fn shutdown(&mut self) -> Result<Value, ClientError> {
        self.call(&Request::Shutdown {})
    }

    /// Says goodbye; the server closes the connection.
    pub fn bye(mut self) -> Result<(), ClientError> {
        self.call::<Value>(&Request::Bye {}).map(|_| ())
    }
}
