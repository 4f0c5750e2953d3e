//! "Did you mean" suggestions: the nearest known name to a misspelt one.

/// Levenshtein distance in characters (for "did you mean" suggestions): `strsim`'s, the crate
/// clap already uses for its own suggestions.
#[must_use]
pub fn edit_distance(a: &str, b: &str) -> usize {
    strsim::levenshtein(a, b)
}

/// The candidate nearest to `word` by edit distance, if it is close enough to be a likely typo
/// (distance ≤ max(2, len/3)) or contains / is contained in `word`.
pub fn nearest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<String> {
    let w = word.to_lowercase();
    candidates
        .into_iter()
        .map(|c| (edit_distance(&w, &c.to_lowercase()), c))
        .filter(|(d, c)| {
            *d <= (w.chars().count() / 3).max(2)
                || (!w.is_empty() && (c.contains(w.as_str()) || w.contains(*c)))
        })
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c.to_string())
}
