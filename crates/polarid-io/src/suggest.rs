//! "Did you mean …?": the names nearest to a mistyped one (library names, material
//! names).

/// Levenshtein distance between `a` and `b` (insertions, deletions, substitutions of
/// characters, each 1).
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.chars().enumerate() {
        cur[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

/// Lower-case alphanumeric words of `s` (`"Gold (Au)"` → `gold`, `au`;
/// `stainless_steel_austenitic` → `stainless`, `steel`, `austenitic`).
fn words(s: &str) -> Vec<String> {
    s.split(|c: char| !c.is_alphanumeric())
        .filter(|w| !w.is_empty())
        .map(str::to_lowercase)
        .collect()
}

/// How far `query` is from `candidate`: the edit distance `d` of the lower-cased names, or
/// 1 when a word of three or more letters of the query is a word of the candidate
/// (`Gold (Au)` and `gold`, `stainless steel` and `stainless_steel_austenitic`); and `d`.
fn distance(query: &str, candidate: &str) -> (usize, usize) {
    let d = edit_distance(&query.to_lowercase(), &candidate.to_lowercase());
    let (q, c) = (words(query), words(candidate));
    let shared = q.iter().any(|w| w.chars().count() >= 3 && c.contains(w));
    (if shared { d.min(1) } else { d }, d)
}

/// The candidates nearest to `query` (at most three, nearest first, ties in candidate
/// order): those within an edit distance of a third of the query's length (at least 1) or
/// sharing a word with it. Empty when nothing is near.
pub fn nearest<'a>(query: &str, candidates: impl IntoIterator<Item = &'a str>) -> Vec<&'a str> {
    let limit = (query.chars().count() / 3).max(1);
    let mut scored: Vec<((usize, usize), usize, &str)> = Vec::new();
    for (i, c) in candidates.into_iter().enumerate() {
        if scored.iter().any(|s| s.2 == c) {
            continue;
        }
        let d = distance(query, c);
        if d.0 <= limit {
            scored.push((d, i, c));
        }
    }
    scored.sort_unstable();
    scored.into_iter().take(3).map(|s| s.2).collect()
}

/// `"; did you mean `a`?"` or `"; did you mean `a`, `b` or `c`?"`, or empty when no
/// candidate is near ([`nearest`]).
pub fn did_you_mean<'a>(query: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    let near: Vec<String> = nearest(query, candidates)
        .into_iter()
        .map(|s| format!("`{s}`"))
        .collect();
    match near.as_slice() {
        [] => String::new(),
        [one] => format!("; did you mean {one}?"),
        [init @ .., last] => format!("; did you mean {} or {last}?", init.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(edit_distance("bultin", "builtin"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("résumé", "resume"), 2);
    }

    #[test]
    fn suggestions() {
        let libs = ["builtin", "builtin-rgb", "paper2007"];
        assert_eq!(nearest("bultin", libs), ["builtin"]);
        assert_eq!(nearest("builtin_rgb", libs), ["builtin-rgb", "builtin"]);
        assert_eq!(nearest("paper2077", libs), ["paper2007"]);
        assert!(nearest("my_library.csv", libs).is_empty());
        let mats = [
            "aluminum",
            "copper",
            "gold",
            "stainless_steel_austenitic",
            "silver",
        ];
        assert_eq!(nearest("Gold (Au)", mats), ["gold"]);
        assert_eq!(nearest("Aluminium", mats), ["aluminum"]);
        assert_eq!(
            nearest("stainless steel", mats),
            ["stainless_steel_austenitic"]
        );
        assert!(nearest("wood", mats).is_empty());
        assert_eq!(did_you_mean("bultin", libs), "; did you mean `builtin`?");
        assert_eq!(
            did_you_mean("builtin_rgb", libs),
            "; did you mean `builtin-rgb` or `builtin`?"
        );
        assert_eq!(did_you_mean("zzzzzzzz", libs), "");
    }
}
