//! A real browser for the end-to-end tests of a web page: Debian's
//! chromium, headless, driven by Selenium through `tests/web/browser.py`
//! (one JSON request a line on its stdin, one JSON answer a line on its
//! stdout; the requests are that script's ops). `tests/demo/` signs in to
//! the demo's web page with it.

use std::io::{BufRead, BufReader, Write};
use std::path::Path;
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::{Duration, Instant};

use serde_json::{Value, json};

/// Whether Selenium, chromium and chromedriver are installed; when not,
/// the test fails saying how to install them, unless skipping is asked
/// for ([`super::tool_missing`]).
pub fn browser_available() -> bool {
    if !super::door::python_client_available("selenium", "selenium") {
        return false;
    }
    let missing: Vec<&str> = ["/usr/bin/chromium", "/usr/bin/chromedriver"]
        .into_iter()
        .filter(|p| !Path::new(p).exists())
        .collect();
    if !missing.is_empty() {
        super::tool_missing(&format!(
            "{missing:?} missing (apt-get install chromium chromium-driver; ./test.sh installs them)"
        ));
        return false;
    }
    true
}

/// `tests/web/browser.py` running its browser.
pub struct Browser {
    child: Child,
    /// Closed on drop: the script then quits the browser and exits.
    stdin: Option<ChildStdin>,
    stdout: BufReader<ChildStdout>,
}

impl Browser {
    /// The longest the script may take to quit the browser when dropped.
    const QUIT: Duration = Duration::from_secs(15);

    /// The script started, its browser ready.
    pub fn start() -> Self {
        Self::launch(&[])
    }

    /// [`Browser::start`] with the script's `args` (`--accept-insecure-certs`).
    pub fn launch(args: &[&str]) -> Self {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/web/browser.py");
        let mut child = Command::new(super::door::python())
            .arg(script)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("run tests/web/browser.py");
        let stdin = child.stdin.take();
        let stdout = BufReader::new(child.stdout.take().expect("stdout"));
        let mut b = Self { child, stdin, stdout };
        assert_eq!(b.read(), json!({ "ok": "ready" }));
        b
    }

    fn read(&mut self) -> Value {
        let mut line = String::new();
        self.stdout.read_line(&mut line).expect("read the browser's answer");
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("the browser's answer is not JSON ({e}): {line:?}"))
    }

    /// Runs `request` (the script bounds each of its waits); its `ok`
    /// value. A failure fails the test, with `log`.
    pub fn call(&mut self, request: Value, log: impl FnOnce() -> String) -> Value {
        let stdin = self.stdin.as_mut().expect("the browser's stdin is open until drop");
        writeln!(stdin, "{request}").expect("write to the browser");
        let answer = self.read();
        match answer.get("ok") {
            Some(ok) => ok.clone(),
            None => panic!("{request}: {answer}\n{}", log()),
        }
    }
}

impl Drop for Browser {
    /// Closes the script's stdin, so that it quits the browser (chromedriver
    /// and every chromium process with it) and exits; kills it only when it
    /// has not within [`Browser::QUIT`].
    fn drop(&mut self) {
        drop(self.stdin.take());
        let until = Instant::now() + Self::QUIT;
        while Instant::now() < until {
            match self.child.try_wait() {
                Ok(None) => std::thread::sleep(Duration::from_millis(50)),
                Ok(Some(_)) | Err(_) => return,
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
