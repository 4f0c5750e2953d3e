//! The one writer every command prints its results through.
//!
//! A closed pipe (`rgbn ops | head -1`) is not an error: output stops quietly and the command
//! goes on to finish its work (files are still written) and exits 0. Any other write failure
//! (e.g. stdout on a full device) is a [`CliError::Stdout`].

use super::error::CliError;
use std::fmt::Display;
use std::io::{ErrorKind, Write};

/// Line-oriented output of a command.
pub struct Out<'a> {
    w: &'a mut dyn Write,
    closed: bool,
}

impl<'a> Out<'a> {
    /// Prints to `w` (stdout in the binary, a buffer in tests).
    pub fn new(w: &'a mut dyn Write) -> Self {
        Self { w, closed: false }
    }

    /// Writes `s` and a newline.
    ///
    /// # Errors
    /// [`CliError::Stdout`] if writing fails for another reason than a closed pipe.
    pub fn line(&mut self, s: impl Display) -> Result<(), CliError> {
        if self.closed {
            return Ok(());
        }
        let r = writeln!(self.w, "{s}");
        self.check(r)
    }

    /// Flushes what is buffered (at the end of a command).
    ///
    /// # Errors
    /// As [`Out::line`].
    pub fn flush(&mut self) -> Result<(), CliError> {
        if self.closed {
            return Ok(());
        }
        let r = self.w.flush();
        self.check(r)
    }

    fn check(&mut self, r: std::io::Result<()>) -> Result<(), CliError> {
        match r {
            Err(e) if e.kind() == ErrorKind::BrokenPipe => {
                self.closed = true;
                Ok(())
            }
            Err(e) => Err(CliError::Stdout(e)),
            Ok(()) => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A writer that fails every write with `kind`.
    struct Failing(ErrorKind, usize);
    impl Write for Failing {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            self.1 += 1;
            Err(std::io::Error::from(self.0))
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Err(std::io::Error::from(self.0))
        }
    }

    #[test]
    fn lines_are_written() {
        let mut buf = Vec::new();
        let mut out = Out::new(&mut buf);
        out.line("a").unwrap();
        out.line(format_args!("{}-{}", 1, 2)).unwrap();
        out.flush().unwrap();
        assert_eq!(buf, b"a\n1-2\n");
    }

    #[test]
    fn a_closed_pipe_stops_output_quietly() {
        let mut w = Failing(ErrorKind::BrokenPipe, 0);
        let mut out = Out::new(&mut w);
        out.line("a").unwrap();
        out.line("b").unwrap();
        out.flush().unwrap();
        assert_eq!(w.1, 1, "nothing is written after the pipe closed");
    }

    #[test]
    fn other_write_errors_are_errors() {
        let mut w = Failing(ErrorKind::StorageFull, 0);
        let mut out = Out::new(&mut w);
        let e = out.line("a").unwrap_err();
        assert!(matches!(e, CliError::Stdout(_)), "{e}");
        assert_eq!(e.exit(), super::super::error::Exit::Usage);
    }
}
