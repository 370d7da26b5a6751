//! The live view: a local web page that shows a live run's fields as they arrive.
//!
//! A small HTTP/1.1 server on the standard library: `GET /` is the page
//! ([`live_view.html`](./live_view.html), no build step, nothing fetched from the internet),
//! `GET /events` a stream of server-sent events (WHATWG HTML, §9.2) that carries the run's
//! description and every update, `GET /image.png` the time-coded event image of the latest
//! field shown, and `GET /state` the latest update as JSON (for scripts). Updates with a field
//! and its image go out at most every [`LIVE_VIEW_INTERVAL`]; the counts with every field.
//!
//! It listens on loopback unless told otherwise: the page has no password.

use crate::error::{Error, Result};
use crate::live::{LiveField, LiveStart};
use crate::render::time_coded_image;
use std::io::{BufRead, BufReader, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// Least time between two fields drawn on the page.
pub const LIVE_VIEW_INTERVAL: Duration = Duration::from_millis(100);

const PAGE: &str = include_str!("live_view.html");

/// Most bytes of a request's head that are read.
const MAX_REQUEST_HEAD: u64 = 16 * 1024;

/// How long an idle event stream waits before a keep-alive comment.
const KEEP_ALIVE: Duration = Duration::from_secs(10);

/// The server of the live view; it stops when dropped.
pub struct LiveView {
    address: SocketAddr,
    shared: Arc<Shared>,
    acceptor: Option<JoinHandle<()>>,
}

#[derive(Default)]
struct Shared {
    state: Mutex<ViewState>,
    changed: Condvar,
    closing: AtomicBool,
    /// Connections being served.
    connections: AtomicUsize,
}

/// Most connections served at once (each page keeps one open for its events).
const MAX_CONNECTIONS: usize = 32;

/// How long a write to a page may block before the connection is given up.
const WRITE_TIMEOUT: Duration = Duration::from_secs(10);

#[derive(Default)]
struct ViewState {
    /// Incremented with every update.
    seq: u64,
    /// The run's description, as JSON.
    start: Option<String>,
    /// The latest update, as JSON.
    update: Option<String>,
    /// The latest event image, PNG.
    image: Option<Vec<u8>>,
}

impl LiveView {
    /// Serve the page at `address` (`127.0.0.1:8080`; port 0: a free one). Addresses other
    /// than loopback need `allow_remote`.
    pub fn start(address: &str, allow_remote: bool) -> Result<Self> {
        let address: SocketAddr = address.parse().map_err(|_| {
            Error::parameter(
                "serve",
                format!("`{address}` is not an address such as 127.0.0.1:8080"),
            )
        })?;
        if !address.ip().is_loopback() && !allow_remote {
            return Err(Error::parameter(
                "serve",
                format!("{address} is reachable from other machines and the page has no password; use 127.0.0.1, or add --allow-remote"),
            ));
        }
        let listener = TcpListener::bind(address)
            .map_err(|e| Error::parameter("serve", format!("cannot listen on {address}: {e}")))?;
        let address = listener
            .local_addr()
            .map_err(|e| Error::parameter("serve", e.to_string()))?;
        listener
            .set_nonblocking(true)
            .map_err(|e| Error::parameter("serve", e.to_string()))?;
        let shared = Arc::new(Shared::default());
        let acceptor = {
            let shared = shared.clone();
            std::thread::spawn(move || accept(listener, shared))
        };
        Ok(LiveView {
            address,
            shared,
            acceptor: Some(acceptor),
        })
    }

    /// The address served.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// Tell the page about the run.
    pub fn started(&self, start: &LiveStart) {
        let json = serde_json::json!({
            "description": start.description,
            "source": start.source,
            "width": start.geometry.width,
            "height": start.geometry.height,
            "step_us": start.step_us,
            "calibrated": start.calibration.is_some(),
        });
        self.update(|s| s.start = Some(json.to_string()));
    }

    /// Pass a field on: its counts always; its vectors and event image when it carries its
    /// events (every [`LIVE_VIEW_INTERVAL`]).
    pub fn publish(&self, start: &LiveStart, f: &LiveField) {
        let mut message = serde_json::json!({
            "t0_us": f.t0_us,
            "t_ms": (f.t0_us - start.time_origin_us) as f64 / 1e3,
            "stats": f.stats,
        });
        let mut image = None;
        if let Some(events) = f.events {
            let field = f.field;
            let value = |v: f32| if v.is_finite() { Some(v) } else { None };
            let (a, b) = f.interval_us;
            let half = (f.t0_us - a).max(b - f.t0_us);
            let picture = time_coded_image(
                events,
                start.geometry,
                f.t0_us,
                half,
                crate::event::PolaritySelection::Both,
            );
            let mut png = Vec::new();
            let encoder = image::codecs::png::PngEncoder::new_with_quality(
                &mut png,
                image::codecs::png::CompressionType::Fast,
                image::codecs::png::FilterType::Sub,
            );
            if image::ImageEncoder::write_image(
                encoder,
                picture.image.as_raw(),
                picture.image.width(),
                picture.image.height(),
                image::ExtendedColorType::Rgb8,
            )
            .is_ok()
            {
                image = Some(png);
            }
            message["field"] = serde_json::json!({
                "x": start.x,
                "y": start.y,
                "u": field.u.iter().map(|&v| value(v)).collect::<Vec<_>>(),
                "v": field.v.iter().map(|&v| value(v)).collect::<Vec<_>>(),
                "valid": field.status.iter().map(|s| u8::from(s.is_valid())).collect::<Vec<_>>(),
                "events": picture.events,
                "half_width_us": half,
            });
        }
        let text = message.to_string();
        self.update(|s| {
            if image.is_some() {
                s.image = image;
            }
            s.update = Some(text);
        });
    }

    fn update(&self, change: impl FnOnce(&mut ViewState)) {
        let mut state = self.shared.state.lock().unwrap_or_else(|p| p.into_inner());
        change(&mut state);
        state.seq += 1;
        self.shared.changed.notify_all();
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        self.shared.closing.store(true, Ordering::SeqCst);
        self.shared.changed.notify_all();
        if let Some(acceptor) = self.acceptor.take() {
            let _ = acceptor.join();
        }
    }
}

fn accept(listener: TcpListener, shared: Arc<Shared>) {
    while !shared.closing.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((mut stream, _)) => {
                if shared.connections.load(Ordering::SeqCst) >= MAX_CONNECTIONS {
                    let _ = stream.set_nonblocking(false);
                    let _ = respond(
                        &mut stream,
                        "503 Service Unavailable",
                        "text/plain",
                        b"too many connections\n",
                    );
                    continue;
                }
                shared.connections.fetch_add(1, Ordering::SeqCst);
                let worker = shared.clone();
                let spawned = std::thread::Builder::new()
                    .name("ebiv-live-view".into())
                    .spawn(move || {
                        let _ = serve(stream, &worker);
                        worker.connections.fetch_sub(1, Ordering::SeqCst);
                    });
                if spawned.is_err() {
                    shared.connections.fetch_sub(1, Ordering::SeqCst);
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
}

/// Answer one request (the connection closes after it).
fn serve(stream: TcpStream, shared: &Shared) -> std::io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(Duration::from_secs(5)))?;
    stream.set_write_timeout(Some(WRITE_TIMEOUT))?;
    let mut reader = BufReader::new(std::io::Read::take(stream.try_clone()?, MAX_REQUEST_HEAD));
    let mut request_line = String::new();
    reader.read_line(&mut request_line)?;
    // The rest of the head (headers) is read and ignored.
    let mut line = String::new();
    while reader.read_line(&mut line)? > 0 && line != "\r\n" && line != "\n" {
        line.clear();
    }
    let mut parts = request_line.split_whitespace();
    let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
    let path = target.split('?').next().unwrap_or("");
    let mut out = stream;
    if method != "GET" {
        return respond(
            &mut out,
            "405 Method Not Allowed",
            "text/plain",
            b"only GET\n",
        );
    }
    match path {
        "/" | "/index.html" => respond(
            &mut out,
            "200 OK",
            "text/html; charset=utf-8",
            PAGE.as_bytes(),
        ),
        "/events" => stream_events(&mut out, shared),
        "/image.png" => {
            let image = shared
                .state
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .image
                .clone();
            match image {
                Some(png) => respond(&mut out, "200 OK", "image/png", &png),
                None => respond(&mut out, "404 Not Found", "text/plain", b"no image yet\n"),
            }
        }
        "/state" => {
            let update = shared
                .state
                .lock()
                .unwrap_or_else(|p| p.into_inner())
                .update
                .clone();
            let body = update.unwrap_or_else(|| "{}".into());
            respond(&mut out, "200 OK", "application/json", body.as_bytes())
        }
        _ => respond(&mut out, "404 Not Found", "text/plain", b"not found\n"),
    }
}

fn respond(out: &mut TcpStream, status: &str, kind: &str, body: &[u8]) -> std::io::Result<()> {
    write!(
        out,
        "HTTP/1.1 {status}\r\nContent-Type: {kind}\r\nContent-Length: {}\r\nCache-Control: no-store\r\nConnection: close\r\n\r\n",
        body.len()
    )?;
    out.write_all(body)?;
    out.flush()
}

/// Server-sent events: the run's description, then every update, until the view closes or
/// the page goes away.
fn stream_events(out: &mut TcpStream, shared: &Shared) -> std::io::Result<()> {
    write!(
        out,
        "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\nConnection: keep-alive\r\n\r\n"
    )?;
    out.flush()?;
    let mut sent_seq = 0;
    let mut sent_start = false;
    loop {
        let (start, update) = {
            let mut state = shared.state.lock().unwrap_or_else(|p| p.into_inner());
            while state.seq == sent_seq && !shared.closing.load(Ordering::SeqCst) {
                let (next, timeout) = shared
                    .changed
                    .wait_timeout(state, KEEP_ALIVE)
                    .unwrap_or_else(|p| p.into_inner());
                state = next;
                if timeout.timed_out() {
                    break;
                }
            }
            if shared.closing.load(Ordering::SeqCst) {
                let _ = out.write_all(b"event: end\ndata: {}\n\n");
                return out.flush();
            }
            let fresh = state.seq != sent_seq;
            sent_seq = state.seq;
            let start = if sent_start {
                None
            } else {
                state.start.clone()
            };
            (start, if fresh { state.update.clone() } else { None })
        };
        if let Some(start) = start {
            write!(out, "event: start\ndata: {start}\n\n")?;
            sent_start = true;
        }
        match update {
            Some(update) => write!(out, "event: update\ndata: {update}\n\n")?,
            None => out.write_all(b": keep-alive\n\n")?,
        }
        out.flush()?;
    }
}
