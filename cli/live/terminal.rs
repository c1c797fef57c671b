//! The terminal of the live view: the alternate screen in raw mode while the view is up (restored on
//! drop, also on an error), frames drawn on demand, and the `q` key (or Ctrl-C, which raw mode turns
//! into a key) read without blocking.

use std::io::IsTerminal as _;
use std::time::Duration;

use ratatui::DefaultTerminal;
use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};

use super::state::LiveState;

/// The live view on the terminal.
pub struct LiveTerminal {
    terminal: DefaultTerminal,
}

impl LiveTerminal {
    /// Whether a live view can be shown: stdout and stderr are terminals.
    pub fn available() -> bool {
        std::io::stdout().is_terminal() && std::io::stderr().is_terminal()
    }

    /// Takes over the terminal (alternate screen, raw mode).
    pub fn start() -> std::io::Result<Self> {
        Ok(Self { terminal: ratatui::try_init()? })
    }

    /// Draws `state`.
    pub fn draw(&mut self, state: &LiveState) -> std::io::Result<()> {
        self.terminal.draw(|f| super::view::draw(f, state)).map(|_| ())
    }

    /// Whether `q`, Esc or Ctrl-C was pressed (waits at most `wait` for a key).
    pub fn quit_pressed(&mut self, wait: Duration) -> bool {
        while event::poll(wait).unwrap_or(false) {
            if let Ok(Event::Key(k)) = event::read()
                && k.kind == KeyEventKind::Press
                && (matches!(k.code, KeyCode::Char('q') | KeyCode::Esc)
                    || (k.code == KeyCode::Char('c') && k.modifiers.contains(KeyModifiers::CONTROL)))
            {
                return true;
            }
        }
        false
    }
}

impl Drop for LiveTerminal {
    fn drop(&mut self) {
        ratatui::restore();
    }
}
