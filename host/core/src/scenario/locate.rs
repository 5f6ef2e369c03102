//! Where a field is in the file: line and column for error messages.

/// One path element of a field, for locating it in the file.
enum Seg<'a> {
    Key(&'a str),
    Index(usize),
}

fn split_path(path: &str) -> Vec<Seg<'_>> {
    let mut out = Vec::new();
    for part in path.split('.').filter(|p| !p.is_empty()) {
        let (key, rest) = part.split_once('[').unwrap_or((part, ""));
        if !key.is_empty() {
            out.push(Seg::Key(key));
        }
        for idx in rest.split('[') {
            if let Ok(i) = idx.trim_end_matches(']').parse() {
                out.push(Seg::Index(i));
            }
        }
    }
    out
}

pub(super) fn line_col(src: &str, offset: usize) -> (usize, usize) {
    let before = &src[..offset.min(src.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    (line, col)
}

/// Where the deepest existing part of `path` is in the file.
pub(super) fn locate(src: &str, path: &str) -> Option<(usize, usize)> {
    let root = toml::de::DeTable::parse(src).ok()?;
    let mut span = root.span();
    let root = toml::de::DeValue::Table(root.into_inner());
    let mut value = &root;
    for seg in split_path(path) {
        let next = match seg {
            Seg::Key(k) => value.get(k),
            Seg::Index(i) => value.get(i),
        };
        match next {
            Some(v) => {
                span = v.span();
                value = v.get_ref();
            }
            None => break,
        }
    }
    Some(line_col(src, span.start))
}
