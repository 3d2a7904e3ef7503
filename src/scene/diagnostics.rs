//! Span diagnostics of the scene file: where each key of the TOML document is, so that any error
//! can name the file, the line and the field.

use super::*;

struct SpanEntry {
    path: String,
    /// The key (or, for an array element, the element itself): what a line number points at.
    key: Range<usize>,
    value: Range<usize>,
}

pub(super) struct SourceMap {
    pub(super) file: PathBuf,
    entries: Vec<SpanEntry>,
    by_path: HashMap<String, usize>,
    line_starts: Vec<usize>,
}

impl SourceMap {
    /// Parses `text` for its key spans; a TOML syntax error comes back as a scene error.
    pub(super) fn new(text: &str, file: &Path) -> Result<SourceMap> {
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        let (table, errors) = toml::de::DeTable::parse_recoverable(text);
        let mut map = SourceMap {
            file: file.to_path_buf(),
            entries: Vec::new(),
            by_path: HashMap::new(),
            line_starts,
        };
        map.collect_table(table.get_ref(), "");
        if let Some(err) = errors.first() {
            let span = err.span();
            let field = span
                .as_ref()
                .and_then(|s| map.field_at(s.start))
                .unwrap_or_else(|| "(syntax)".to_string());
            return Err(PrtError::Scene {
                path: map.file.clone(),
                line: span.map(|s| map.line_at(s.start)),
                field,
                message: err.message().trim().to_string(),
            });
        }
        Ok(map)
    }

    pub(super) fn collect_table(&mut self, table: &toml::de::DeTable<'_>, prefix: &str) {
        for (key, value) in table.iter() {
            let path = if prefix.is_empty() {
                key.get_ref().to_string()
            } else {
                format!("{prefix}.{}", key.get_ref())
            };
            self.push(path.clone(), key.span(), value.span());
            self.collect_value(value.get_ref(), &path);
        }
    }

    pub(super) fn collect_value(&mut self, value: &toml::de::DeValue<'_>, path: &str) {
        if let Some(table) = value.as_table() {
            self.collect_table(table, path);
        } else if let Some(array) = value.as_array() {
            for (i, element) in array.iter().enumerate() {
                let element_path = format!("{path}[{i}]");
                self.push(element_path.clone(), element.span(), element.span());
                self.collect_value(element.get_ref(), &element_path);
            }
        }
    }

    pub(super) fn push(&mut self, path: String, key: Range<usize>, value: Range<usize>) {
        self.by_path.insert(path.clone(), self.entries.len());
        self.entries.push(SpanEntry { path, key, value });
    }

    /// 1-based line of a byte offset.
    pub(super) fn line_at(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&start| start <= offset)
    }

    /// The innermost field whose key or value covers `offset`.
    pub(super) fn field_at(&self, offset: usize) -> Option<String> {
        let covers = |r: &Range<usize>| r.start <= offset && (offset < r.end || r.is_empty());
        self.entries
            .iter()
            .flat_map(|e| [(e, &e.key), (e, &e.value)])
            .filter(|(_, r)| covers(r))
            .min_by_key(|(e, r)| (r.len(), std::cmp::Reverse(e.path.len())))
            .map(|(e, _)| e.path.clone())
    }

    /// Line of `field`, or of the nearest enclosing field present in the file (a defaulted key
    /// has no line of its own).
    pub(super) fn line_of(&self, field: &str) -> Option<usize> {
        let mut path = field;
        loop {
            if let Some(&i) = self.by_path.get(path) {
                return Some(self.line_at(self.entries[i].key.start));
            }
            let cut = path.rfind(['.', '['])?;
            path = &path[..cut];
        }
    }

    pub(super) fn error(&self, field: &str, message: impl Into<String>) -> PrtError {
        PrtError::Scene {
            path: self.file.clone(),
            line: self.line_of(field),
            field: field.to_string(),
            message: message.into(),
        }
    }

    /// Turns a schema error from serde (unknown key, wrong type, missing key) into a scene
    /// error naming the field.
    pub(super) fn schema_error(&self, err: &toml::de::Error) -> PrtError {
        let message = err.message().trim().to_string();
        // An error spanning from the top of the document is about the document itself (a
        // missing top-level table), not about the first key in it.
        let located = err
            .span()
            .filter(|s| s.start > 0)
            .and_then(|s| self.field_at(s.start));
        // A missing key is reported at its table; name the key itself.
        let missing = message
            .strip_prefix("missing field `")
            .and_then(|rest| rest.split('`').next());
        let field = match (located, missing) {
            (Some(table), Some(key)) => format!("{table}.{key}"),
            (None, Some(key)) => key.to_string(),
            (Some(field), None) => field,
            (None, None) => "(document)".to_string(),
        };
        PrtError::Scene {
            path: self.file.clone(),
            line: err.span().map(|s| self.line_at(s.start)),
            field,
            message,
        }
    }
}
