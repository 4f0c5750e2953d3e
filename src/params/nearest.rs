//! "Did you mean" suggestions: the nearest known name to a misspelt one.

/// Levenshtein distance (for "did you mean" suggestions).
#[must_use]
pub fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.iter().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != cb))
                .min(prev[j + 1] + 1)
                .min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
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
