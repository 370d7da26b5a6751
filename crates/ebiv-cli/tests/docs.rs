//! `--help` and the reference pages in `docs/` name the same options: every option a command's
//! `--help` lists is described on its page, and every option a page describes exists.

mod common;
use common::{ebiv, stdout};
use std::collections::BTreeSet;
use std::path::PathBuf;

/// Where commands are described: the commands, the page, and the heading that opens their
/// section (the section runs to the next heading of the same level), or the whole page.
const PAGES: [(&[&str], &str, Option<&str>); 16] = [
    (&["info"], "commands.md", Some("## `ebiv info")),
    (&["index"], "commands.md", Some("## `ebiv index")),
    (&["convert"], "commands.md", Some("## `ebiv convert")),
    (&["render"], "commands.md", Some("## `ebiv render")),
    (&["frames"], "commands.md", Some("## `ebiv frames")),
    (&["demo"], "commands.md", Some("## `ebiv demo")),
    (&["init"], "commands.md", Some("## `ebiv init")),
    (
        &["filter"],
        "denoise.md",
        Some("## Options of `ebiv filter`"),
    ),
    (&["process"], "process.md", None),
    (&["simulate"], "simulate.md", None),
    (&["stats"], "statistics.md", Some("## Options")),
    (&["derive"], "derived.md", Some("## Options")),
    (&["study"], "study.md", None),
    (&["track"], "tracking.md", Some("## Options")),
    // `ebiv live` also takes every setting of `ebiv process` (documented in process.md).
    (&["live"], "live.md", Some("## Options")),
    (
        &[
            "bench decode",
            "bench simulate",
            "bench process",
            "bench piv",
            "bench envelope",
            "bench track",
        ],
        "performance.md",
        Some("## Running the benchmarks"),
    ),
];

/// Options every reading command shares (`ebiv info --help` lists them); they are described
/// once, in this section of commands.md.
const READING_SECTION: &str = "## Reading options";

fn docs_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs")
}

/// The long options a `--help` text lists (its option lines, with their visible aliases; not
/// its prose).
fn help_options(args: &[&str]) -> BTreeSet<String> {
    let mut full: Vec<&str> = args.to_vec();
    full.push("--help");
    let out = ebiv(&full);
    assert!(out.status.success(), "ebiv {full:?} failed");
    let mut options = BTreeSet::new();
    for line in stdout(&out).lines() {
        // `[alias: --passes]` or `[aliases: --a, --b]`, after the option's help.
        if let Some((_, aliases)) = line
            .split_once("[alias: ")
            .or_else(|| line.split_once("[aliases: "))
        {
            let aliases = aliases.split(']').next().unwrap_or_default();
            options.extend(aliases.split(", ").map(option_name));
        }
        let line = line.trim_start();
        // `--output …`, or `-o, --output …`
        let Some(line) = (if line.starts_with("--") {
            Some(line)
        } else {
            line.strip_prefix('-')
                .and_then(|l| l.split_once(", "))
                .map(|(_, rest)| rest)
        }) else {
            continue;
        };
        let name = option_name(line);
        if !name.starts_with("--") {
            continue;
        }
        options.insert(name);
    }
    options.remove("--help");
    options.remove("--version");
    options
}

/// The option name at the start of `text` (`--slab <DUR>` gives `--slab`).
fn option_name(text: &str) -> String {
    text.trim()
        .chars()
        .take_while(|c| c.is_ascii_alphanumeric() || *c == '-')
        .collect()
}

/// The `--options` a text mentions.
fn mentioned(text: &str) -> BTreeSet<String> {
    let bytes = text.as_bytes();
    let mut found = BTreeSet::new();
    let mut i = 0;
    while i + 2 < bytes.len() {
        let starts = bytes[i] == b'-'
            && bytes[i + 1] == b'-'
            && bytes[i + 2].is_ascii_lowercase()
            && (i == 0 || !(bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'-'));
        if starts {
            let end = (i + 2..bytes.len())
                .find(|&j| !(bytes[j].is_ascii_alphanumeric() || bytes[j] == b'-'))
                .unwrap_or(bytes.len());
            found.insert(text[i..end].trim_end_matches('-').to_string());
            i = end;
        } else {
            i += 1;
        }
    }
    found
}

/// The text of `page` from the heading `start` to the next heading of its level.
fn section(page: &str, start: Option<&str>) -> String {
    let text = std::fs::read_to_string(docs_dir().join(page)).expect("read the docs page");
    let Some(start) = start else { return text };
    let level = start.split(' ').next().unwrap();
    let from = text
        .find(start)
        .unwrap_or_else(|| panic!("{page} has no heading `{start}`"));
    let rest = &text[from + start.len()..];
    let end = rest
        .match_indices('\n')
        .map(|(i, _)| i + 1)
        .find(|&i| rest[i..].starts_with(&format!("{level} ")))
        .unwrap_or(rest.len());
    rest[..end].to_string()
}

#[test]
fn help_and_reference_pages_name_the_same_options() {
    let global = help_options(&[]);
    // The reading options: those every reading command has.
    let reading: BTreeSet<String> = ["info", "convert", "render", "frames", "process"]
        .iter()
        .map(|c| help_options(&[c]))
        .reduce(|a, b| a.intersection(&b).cloned().collect())
        .unwrap();
    let reading_docs = mentioned(&section("commands.md", Some(READING_SECTION)));
    let mut problems = Vec::new();
    for option in &reading {
        if !global.contains(option) && !reading_docs.contains(option) {
            problems.push(format!(
                "{option} (reading option) is not in commands.md `{READING_SECTION}`"
            ));
        }
    }
    for option in &global {
        let conventions = mentioned(&section("commands.md", Some("## Conventions")));
        if !conventions.contains(option) {
            problems.push(format!(
                "{option} (global) is not in commands.md `## Conventions`"
            ));
        }
    }
    let process_settings = help_options(&["process"]);
    for (commands, page, heading) in PAGES {
        let help: BTreeSet<String> = commands
            .iter()
            .flat_map(|c| help_options(&c.split(' ').collect::<Vec<_>>()))
            .collect();
        let command = commands.join(", ");
        let docs = mentioned(&section(page, heading));
        let own: BTreeSet<&String> = help
            .iter()
            .filter(|o| !global.contains(*o) && !reading.contains(*o))
            .filter(|o| page != "live.md" || !process_settings.contains(*o))
            .collect();
        for option in own {
            if !docs.contains(option) {
                problems.push(format!(
                    "ebiv {command}: {option} is in --help but not in {page}"
                ));
            }
        }
        for (line, option) in section(page, heading)
            .lines()
            .flat_map(|line| mentioned(line).into_iter().map(move |o| (line, o)))
        {
            if help.contains(&option) || global.contains(&option) || option == "--help" {
                continue;
            }
            // Options of other programs, on a line that runs them, are theirs; an option on a
            // line that runs another ebiv command must be that command's.
            let other_program = ["cargo ", "valgrind "].iter().any(|p| line.contains(p));
            let other_command = named_commands(line)
                .iter()
                .any(|c| help_options(&[c.as_str()]).contains(&option));
            if !other_program && !other_command {
                problems.push(format!(
                    "ebiv {command}: {page} describes {option}, which --help does not list"
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The ebiv commands a line runs (`ebiv process …` gives `process`).
fn named_commands(line: &str) -> Vec<String> {
    const COMMANDS: [&str; 11] = [
        "info", "index", "convert", "render", "frames", "process", "init", "demo", "simulate",
        "bench", "track",
    ];
    line.match_indices("ebiv ")
        .filter_map(|(i, _)| {
            let word: String = line[i + 5..]
                .chars()
                .take_while(|c| c.is_ascii_lowercase())
                .collect();
            COMMANDS.contains(&word.as_str()).then_some(word)
        })
        .collect()
}

#[test]
fn the_option_scanner_finds_options_and_only_options() {
    let found = mentioned("use --slab 10ms (not -slab), or --no-deform; x--y and --- are not");
    let found: Vec<&str> = found.iter().map(String::as_str).collect();
    assert_eq!(found, ["--no-deform", "--slab"]);
    assert_eq!(
        named_commands("`ebiv process --method piv` builds them; ebiv frames; ebiv x"),
        ["process", "frames"]
    );
}
