//! The IOHeader `infoNode` of AEDAT 4.0: an XML tree written by DV (formats.md §9), e.g.
//!
//! ```text
//! <dv version="2.0">
//!   <node name="outInfo" path="/mainloop/Recorder/outInfo/">
//!     <node name="0" path="/mainloop/Recorder/outInfo/0/">
//!       <attr key="compression" type="string">LZ4</attr>
//!       <attr key="typeIdentifier" type="string">EVTS</attr>
//!       <node name="info" path="/mainloop/Recorder/outInfo/0/info/">
//!         <attr key="sizeX" type="int">320</attr> …
//! ```
//!
//! Only what a reader needs is extracted, with a small tag scanner rather than an XML library:
//! one entry per stream node below `outInfo`, with its own attributes and those of its `info`
//! child.

/// What the info node says about one stream of the file.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(super) struct StreamInfo {
    /// Stream id, as used in packet headers.
    pub id: i32,
    /// Four-character type: `EVTS`, `FRME`, `IMUS`, `TRIG`, …
    pub type_identifier: String,
    /// Sensor width for event and frame streams.
    pub size_x: Option<u32>,
    /// Sensor height for event and frame streams.
    pub size_y: Option<u32>,
    /// Camera name and serial, e.g. `DVXplorer_DXB00010`.
    pub source: Option<String>,
    /// Offset of the camera clock to Unix time (µs); time stamps already include it.
    pub ts_offset: Option<i64>,
    /// Compression named for this stream.
    pub compression: Option<String>,
    /// `originalOutputName`, e.g. `events`.
    pub output_name: Option<String>,
}

/// The streams described by `xml`, sorted by id. Unparseable parts are ignored.
pub(super) fn parse_streams(xml: &str) -> Vec<StreamInfo> {
    let mut streams: Vec<StreamInfo> = Vec::new();
    let mut stack: Vec<String> = Vec::new();
    let mut rest = xml;
    while let Some(open) = rest.find('<') {
        rest = &rest[open..];
        if let Some(after) = rest.strip_prefix("<!--") {
            rest = after.find("-->").map_or("", |end| &after[end + 3..]);
            continue;
        }
        let Some(close) = rest.find('>') else { break };
        let tag = &rest[1..close];
        rest = &rest[close + 1..];
        let self_closing = tag.ends_with('/');
        let tag = tag.trim_end_matches('/');
        if tag.starts_with('/') {
            if tag.trim() == "/node" {
                stack.pop();
            }
            continue;
        }
        let name = tag.split_whitespace().next().unwrap_or("");
        match name {
            "node" if !self_closing => stack.push(attribute(tag, "name").unwrap_or_default()),
            "attr" => {
                let key = attribute(tag, "key").unwrap_or_default();
                let value = if self_closing {
                    String::new()
                } else {
                    let end = rest.find('<').unwrap_or(rest.len());
                    let text = unescape(rest[..end].trim());
                    rest = &rest[end..];
                    text
                };
                if let Some(stream) = stream_of(&stack, &mut streams) {
                    apply(stream, &stack, &key, &value);
                }
            }
            _ => {}
        }
    }
    streams.sort_by_key(|s| s.id);
    streams
}

/// The stream an attribute at `stack` belongs to: `…/outInfo/<id>/` or `…/outInfo/<id>/info/`.
fn stream_of<'s>(stack: &[String], streams: &'s mut Vec<StreamInfo>) -> Option<&'s mut StreamInfo> {
    let out = stack.iter().rposition(|n| n == "outInfo")?;
    let id: i32 = stack.get(out + 1)?.trim().parse().ok()?;
    if stack.len() > out + 3 {
        return None;
    }
    let index = match streams.iter().position(|s| s.id == id) {
        Some(i) => i,
        None => {
            streams.push(StreamInfo {
                id,
                ..StreamInfo::default()
            });
            streams.len() - 1
        }
    };
    streams.get_mut(index)
}

fn apply(stream: &mut StreamInfo, stack: &[String], key: &str, value: &str) {
    let in_info = stack.last().is_some_and(|n| n == "info");
    match (in_info, key) {
        (false, "typeIdentifier") => stream.type_identifier = value.to_string(),
        (false, "compression") => stream.compression = Some(value.to_string()),
        (false, "originalOutputName") => stream.output_name = Some(value.to_string()),
        (true, "sizeX") => stream.size_x = value.trim().parse().ok(),
        (true, "sizeY") => stream.size_y = value.trim().parse().ok(),
        (true, "source") => stream.source = Some(value.to_string()),
        (true, "tsOffset") => stream.ts_offset = value.trim().parse().ok(),
        _ => {}
    }
}

/// The value of attribute `name="…"` in a tag's text.
fn attribute(tag: &str, name: &str) -> Option<String> {
    let mut search = tag;
    loop {
        let at = search.find(name)?;
        let before_ok = at == 0
            || search[..at]
                .chars()
                .next_back()
                .is_some_and(char::is_whitespace);
        let after = search[at + name.len()..].trim_start();
        if before_ok {
            if let Some(value) = after.strip_prefix('=') {
                let value = value.trim_start();
                let quote = value.chars().next()?;
                if quote == '"' || quote == '\'' {
                    let body = &value[1..];
                    let end = body.find(quote)?;
                    return Some(unescape(&body[..end]));
                }
            }
        }
        search = &search[at + name.len()..];
    }
}

fn unescape(text: &str) -> String {
    if !text.contains('&') {
        return text.to_string();
    }
    text.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&apos;", "'")
        .replace("&amp;", "&")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_of_a_dv_info_node() {
        let xml = r#"<dv version="2.0">
    <node name="outInfo" path="/mainloop/Recorder/outInfo/">
        <node name="3" path="/mainloop/Recorder/outInfo/3/">
            <attr key="typeIdentifier" type="string">TRIG</attr>
        </node>
        <node name="0" path="/mainloop/Recorder/outInfo/0/">
            <attr key="compression" type="string">LZ4</attr>
            <attr key="typeIdentifier" type="string">EVTS</attr>
            <!-- a comment <node name="9"> -->
            <node name="info" path="/mainloop/Recorder/outInfo/0/info/">
                <attr key="sizeX" type="int">320</attr>
                <attr key="sizeY" type="int">240</attr>
                <attr key="source" type="string">DVXplorer_&amp;1</attr>
                <attr key="tsOffset" type="long">1605507430438338</attr>
                <attr key="empty" type="string"/>
            </node>
        </node>
    </node>
</dv>"#;
        let s = parse_streams(xml);
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].id, 0);
        assert_eq!(s[0].type_identifier, "EVTS");
        assert_eq!((s[0].size_x, s[0].size_y), (Some(320), Some(240)));
        assert_eq!(s[0].source.as_deref(), Some("DVXplorer_&1"));
        assert_eq!(s[0].ts_offset, Some(1605507430438338));
        assert_eq!(s[0].compression.as_deref(), Some("LZ4"));
        assert_eq!(s[1].id, 3);
        assert_eq!(s[1].type_identifier, "TRIG");
    }

    #[test]
    fn garbage_does_not_panic() {
        for xml in [
            "<",
            "<node",
            "<attr key=\"x>",
            "<node name='1'><attr key=",
            "é<ü>ß",
        ] {
            let _ = parse_streams(xml);
        }
    }
}
