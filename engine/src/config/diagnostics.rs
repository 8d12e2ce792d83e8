//! Error messages about the experiment file that name the key path and its own line.
//!
//! serde reports a wrong value inside a tagged table (`[atmosphere]` with `type = ...`) at the
//! table, and the TOML reader quotes the table's header line; [`mod@super::resolve`] finds the real
//! offender by its value or name, and these helpers quote *its* line instead, cut to a readable
//! length (a 200 KB line is never echoed whole).

/// Longest source line quoted in a message, characters.
pub const MAX_QUOTED: usize = 160;
/// Longest line of a message (lists of allowed keys fit; a 200 KB value does not).
pub const MAX_MESSAGE_LINE: usize = 600;

/// `line` cut to [`MAX_QUOTED`] characters, saying how long it was.
pub fn cut(line: &str) -> String {
    cut_to(line, MAX_QUOTED)
}

fn cut_to(line: &str, max: usize) -> String {
    let n = line.chars().count();
    if n <= max {
        line.to_string()
    } else {
        let head: String = line.chars().take(max).collect();
        format!("{head}… ({n} characters, cut)")
    }
}

/// Every line of `message` cut to [`MAX_MESSAGE_LINE`] characters.
pub fn cut_lines(message: &str) -> String {
    message
        .lines()
        .map(|l| cut_to(l, MAX_MESSAGE_LINE))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The TOML reader's message without its quoted snippet: ("line N" if it gave one, the core).
pub fn split_toml_message(message: &str) -> (Option<usize>, String) {
    const HEAD: &str = "TOML parse error at line ";
    let Some(rest) = message.strip_prefix(HEAD) else {
        return (None, message.to_string());
    };
    let line = rest
        .split(|c: char| !c.is_ascii_digit())
        .next()
        .and_then(|d| d.parse().ok());
    // The core follows the caret line of the snippet.
    let lines: Vec<&str> = message.lines().collect();
    let core = match lines
        .iter()
        .rposition(|l| l.trim_start().starts_with('|') && l.contains('^'))
    {
        Some(k) => lines[k + 1..].join("\n"),
        None => lines[1..].join("\n"),
    };
    (line, core.trim().to_string())
}

/// 1-based line of the key at `path` (e.g. `atmosphere.optical_thickness`,
/// `measures[1].spp`, `atmosphere.phase.type`) in `text`: the first line after the header of the
/// longest table prefix (the k-th `[[name]]` for `name[k]`) that assigns one of the remaining
/// path components (the first of them). None when it cannot be found.
pub fn line_of(text: &str, path: &str) -> Option<usize> {
    let parts: Vec<(String, Option<usize>)> = path
        .split('.')
        .map(|p| match p.find('[') {
            Some(i) => (
                p[..i].to_string(),
                p[i + 1..].trim_end_matches(']').parse().ok(),
            ),
            None => (p.to_string(), None),
        })
        .collect();
    let lines: Vec<&str> = text.lines().collect();
    let header = |l: &str| -> Option<String> {
        let t = l.trim();
        let t = t.split('#').next()?.trim();
        let inner = t
            .strip_prefix("[[")
            .and_then(|s| s.strip_suffix("]]"))
            .or_else(|| t.strip_prefix('[').and_then(|s| s.strip_suffix(']')))?;
        Some(inner.trim().to_string())
    };
    // Longest prefix of `parts` that is a table header, and where its section starts.
    let mut start = 0usize;
    let mut used = 0usize;
    for n in (1..=parts.len()).rev() {
        let name = parts[..n]
            .iter()
            .map(|(p, _)| p.as_str())
            .collect::<Vec<_>>()
            .join(".");
        let want = parts[n - 1].1.unwrap_or(0);
        let hits: Vec<usize> = lines
            .iter()
            .enumerate()
            .filter(|(_, l)| header(l).as_deref() == Some(name.as_str()))
            .map(|(k, _)| k)
            .collect();
        if let Some(&k) = hits.get(want) {
            start = k + 1;
            used = n;
            break;
        }
    }
    let names: Vec<&str> = parts[used..].iter().map(|(p, _)| p.as_str()).collect();
    if names.is_empty() {
        return Some(start);
    }
    for (k, l) in lines.iter().enumerate().skip(start) {
        if k > start && header(l).is_some() {
            break;
        }
        // The first remaining component is assigned here (deeper ones sit in its inline
        // table on the same line).
        let t = l.trim_start();
        if let Some(rest) = t.strip_prefix(names[0]) {
            if rest.trim_start().starts_with('=') {
                return Some(k + 1);
            }
        }
    }
    None
}

/// The line `n` (1-based) of `text`, quoted and cut: `  12 | optical_thickness = "abc"`.
pub fn quote(text: &str, n: usize) -> Option<String> {
    let l = text.lines().nth(n.checked_sub(1)?)?;
    Some(format!("{n:>5} | {}", cut(l.trim_end())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_lines_of_keys_in_tables_arrays_and_inline_tables() {
        let text = "seed = 1\n[atmosphere]\ntype = \"homogeneous\"\noptical_thickness = \"abc\"\nphase = { type = \"hg\" }\n[[measures]]\nspp = 1\n[[measures]]\nid = \"b\"\nspp = 2\n";
        assert_eq!(line_of(text, "seed"), Some(1));
        assert_eq!(line_of(text, "atmosphere.optical_thickness"), Some(4));
        assert_eq!(line_of(text, "atmosphere.phase.type"), Some(5));
        assert_eq!(line_of(text, "measures[1].spp"), Some(10));
        assert_eq!(line_of(text, "measures[0].spp"), Some(7));
        assert_eq!(line_of(text, "atmosphere.nothing"), None);
        assert_eq!(
            quote(text, 4).unwrap(),
            "    4 | optical_thickness = \"abc\""
        );
        let long = "x".repeat(200_000);
        let q = cut(&long);
        assert!(q.len() < 300 && q.contains("200000 characters"), "{q}");
    }

    #[test]
    fn splits_the_toml_snippet_from_the_message() {
        let m = "TOML parse error at line 12, column 1\n   |\n12 | [atmosphere]\n   | ^^^^^^^^^^^^\ninvalid type: string \"abc\", expected a number\n";
        let (l, core) = split_toml_message(m);
        assert_eq!(l, Some(12));
        assert_eq!(core, "invalid type: string \"abc\", expected a number");
        assert_eq!(split_toml_message("plain").1, "plain");
    }
}
