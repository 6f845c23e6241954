//! Names a user typed: the nearest known one, for did-you-mean messages.

/// ` (did you mean `k`?)` for the known name within two edits of `key`, or "".
pub fn suggest(key: &str, known: &[&str]) -> String {
    let dist = |a: &str, b: &str| {
        let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
        let mut d: Vec<usize> = (0..=b.len()).collect();
        for i in 1..=a.len() {
            let mut prev = d[0];
            d[0] = i;
            for j in 1..=b.len() {
                let cur = d[j];
                d[j] = (d[j] + 1)
                    .min(d[j - 1] + 1)
                    .min(prev + usize::from(a[i - 1] != b[j - 1]));
                prev = cur;
            }
        }
        d[b.len()]
    };
    known
        .iter()
        .map(|k| (dist(key, k), k))
        .filter(|(d, _)| *d <= 2)
        .min()
        .map(|(_, k)| format!(" (did you mean `{k}`?)"))
        .unwrap_or_default()
}
