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
    /// Timings on stderr (`RGBN_EDITOR_TIMING` set).
    pub(super) timing: bool,
}

impl Default for Preferences {
    fn default() -> Self {
        Self {
            settings: PreviewSettings::default(),
            recent: RecentFiles::default(),
            dialog_dir: None,
            timing: std::env::var_os("RGBN_EDITOR_TIMING").is_some(),
        }
    }
}
