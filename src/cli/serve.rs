//! `rgbn serve DIR`: a small static web server on 127.0.0.1 only, so that a published folder
//! is shown at every level (a page opened from disk cannot use image files as WebGL
//! textures). GET and HEAD of files under DIR, keep-alive, nothing else: no directory
//! listings, no paths outside DIR, no other interface than the loopback one.

use super::error::{usage, CliError};
use super::out::Out;
use clap::Args;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{Ipv4Addr, TcpListener, TcpStream};
use std::path::{Component, Path, PathBuf};
use std::time::Duration;

#[derive(Args, Debug)]
pub struct ServeArgs {
    /// The folder to serve (e.g. one written by `rgbn publish`).
    pub dir: PathBuf,
    /// Port on 127.0.0.1 (0: any free port; the address is printed).
    #[arg(long, default_value_t = 8000)]
    pub port: u16,
    /// Print each request (method, path, status) on stderr.
    #[arg(long)]
    pub log: bool,
}

pub(super) fn serve_cmd(a: &ServeArgs, out: &mut Out<'_>) -> Result<(), CliError> {
    if !a.dir.is_dir() {
        return Err(usage(format!(
            "not a folder (give the folder rgbn publish wrote): {}",
            a.dir.display()
        )));
    }
    let root = std::fs::canonicalize(&a.dir)
        .map_err(|e| usage(format!("cannot read the folder ({e}): {}", a.dir.display())))?;
    let listener = TcpListener::bind((Ipv4Addr::LOCALHOST, a.port)).map_err(|e| {
        usage(format!(
            "cannot listen on 127.0.0.1:{} ({e}); choose another --port (0: any free one)",
            a.port
        ))
    })?;
    let port = listener
        .local_addr()
        .map_err(|e| usage(e.to_string()))?
        .port();
    out.line(format_args!(
        "serving {} at http://127.0.0.1:{port}/ (Ctrl-C stops)",
        a.dir.display()
    ))?;
    out.flush()?;
    listener
        .set_nonblocking(true)
        .map_err(|e| usage(e.to_string()))?;
    let log = a.log;
    loop {
        super::interrupt::check()?;
        match listener.accept() {
            Ok((stream, _)) => {
                let root = root.clone();
                std::thread::spawn(move || {
                    let _ = connection(stream, &root, log);
                });
            }
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                std::thread::sleep(Duration::from_millis(20));
            }
            Err(e) => tracing::warn!("rgbn serve: accept failed: {e}"),
        }
    }
}

/// Serves the requests of one connection until it closes (or idles for 30 s).
fn connection(stream: TcpStream, root: &Path, log: bool) -> std::io::Result<()> {
    stream.set_nonblocking(false)?;
    stream.set_read_timeout(Some(Duration::from_secs(30)))?;
    let mut reader = BufReader::new(stream.try_clone()?);
    let mut writer = stream;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line)? == 0 {
            return Ok(());
        }
        let mut keep_alive = line.trim_end().ends_with("HTTP/1.1");
        let mut body_len = 0usize;
        loop {
            let mut h = String::new();
            if reader.read_line(&mut h)? == 0 {
                return Ok(());
            }
            let h = h.trim_end();
            if h.is_empty() {
                break;
            }
            if let Some((k, v)) = h.split_once(':') {
                let (k, v) = (k.trim().to_ascii_lowercase(), v.trim().to_ascii_lowercase());
                if k == "connection" {
                    keep_alive = v != "close";
                } else if k == "content-length" {
                    body_len = v.parse().unwrap_or(0);
                }
            }
        }
        // A body is not expected; skip one if sent.
        std::io::copy(
            &mut (&mut reader).take(body_len as u64),
            &mut std::io::sink(),
        )?;
        let mut parts = line.split_whitespace();
        let (method, target) = (parts.next().unwrap_or(""), parts.next().unwrap_or(""));
        let (status, ctype, body) = respond(method, target, root);
        if log {
            eprintln!("rgbn serve: {method} {target} {status}");
        }
        let head = format!(
            "HTTP/1.1 {status}\r\nContent-Type: {ctype}\r\nContent-Length: {}\r\nCache-Control: no-cache\r\nConnection: {}\r\n\r\n",
            body.len(),
            if keep_alive { "keep-alive" } else { "close" }
        );
        writer.write_all(head.as_bytes())?;
        if method != "HEAD" {
            writer.write_all(&body)?;
        }
        writer.flush()?;
        if !keep_alive {
            return Ok(());
        }
    }
}

/// Status line, content type and body for a request.
fn respond(method: &str, target: &str, root: &Path) -> (&'static str, &'static str, Vec<u8>) {
    let text = "text/plain; charset=utf-8";
    if method != "GET" && method != "HEAD" {
        return (
            "405 Method Not Allowed",
            text,
            b"only GET and HEAD\n".to_vec(),
        );
    }
    let Some(path) = resolve(root, target) else {
        return ("404 Not Found", text, b"not found\n".to_vec());
    };
    match std::fs::read(&path) {
        Ok(bytes) => ("200 OK", content_type(&path), bytes),
        Err(_) => ("404 Not Found", text, b"not found\n".to_vec()),
    }
}

/// The file under `root` that `target` names (`/` and folders: their `index.html`), or `None`
/// for a path that would leave `root`.
fn resolve(root: &Path, target: &str) -> Option<PathBuf> {
    let path = target.split(['?', '#']).next().unwrap_or("");
    let decoded = percent_decode(path)?;
    let mut out = root.to_path_buf();
    for c in Path::new(decoded.trim_start_matches('/')).components() {
        match c {
            Component::Normal(n) => out.push(n),
            Component::CurDir => {}
            _ => return None,
        }
    }
    if out.is_dir() {
        out.push("index.html");
    }
    // Symbolic links out of the folder are not followed.
    let real = std::fs::canonicalize(&out).ok()?;
    real.starts_with(root).then_some(real)
}

fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

fn content_type(p: &Path) -> &'static str {
    match p
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("html" | "htm") => "text/html; charset=utf-8",
        Some("js" | "mjs") => "text/javascript; charset=utf-8",
        Some("json") => "application/json",
        Some("dzi" | "xml") => "application/xml",
        Some("png") => "image/png",
        Some("jpg" | "jpeg") => "image/jpeg",
        Some("css") => "text/css; charset=utf-8",
        Some("svg") => "image/svg+xml",
        Some("txt" | "md") => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_stay_inside_the_folder() {
        let d = tempfile::tempdir().unwrap();
        let root = std::fs::canonicalize(d.path()).unwrap();
        std::fs::create_dir(root.join("a")).unwrap();
        std::fs::write(root.join("a/x y.png"), b"x").unwrap();
        std::fs::write(root.join("index.html"), b"i").unwrap();
        assert_eq!(
            resolve(&root, "/a/x%20y.png?v=1"),
            Some(root.join("a/x y.png"))
        );
        assert_eq!(resolve(&root, "/"), Some(root.join("index.html")));
        assert_eq!(resolve(&root, "/../etc/passwd"), None);
        assert_eq!(resolve(&root, "/a/%2e%2e/%2e%2e/x"), None);
        assert_eq!(respond("GET", "/missing", &root).0, "404 Not Found");
        assert_eq!(respond("POST", "/", &root).0, "405 Method Not Allowed");
        let (s, t, b) = respond("GET", "/a/x%20y.png", &root);
        assert_eq!((s, t, b.as_slice()), ("200 OK", "image/png", &b"x"[..]));
    }
}
