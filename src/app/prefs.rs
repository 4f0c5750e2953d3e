//! Preferences: how the user likes to work, kept across documents (preview settings, recent
//! files, the file dialog's folder, timing output).

use super::preview::PreviewSettings;
use super::recent::RecentFiles;
use std::path::PathBuf;

/// The editor's preferences.
#[derive(Debug)]
pub struct Preferences {
    /// Preview display settings.
    pub settings: PreviewSettings,
    /// Recently used graph files (File ▸ Open recent).
    pub recent: RecentFiles,
    /// The folder the file dialog opens in: the last one used, else the graph's folder.
    pub dialog_dir: Option<PathBuf>,
    /// Timings logged (target [`super::TIMING`] enabled: `RUST_LOG=rgbn::editor::timing=info`,
    /// or `RGBN_EDITOR_TIMING` set).
    pub(super) timing: bool,
}

impl Default for Preferences {
    fn default() -> Self {
        Self {
            settings: PreviewSettings::default(),
            recent: RecentFiles::default(),
            dialog_dir: None,
            timing: super::timing_enabled(),
        }
    }
}
