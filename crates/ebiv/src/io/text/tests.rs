use super::*;
use crate::event::Geometry;
use crate::io::{open_source, Format, ReadOptions, Recording};
use std::io::Cursor;

fn read_with(text: &[u8], options: ReadOptions) -> Result<Recording> {
    let options = ReadOptions {
        format: Some(Format::Text),
        ..options
    };
    open_source(
        Box::new(Cursor::new(text.to_vec())),
        "test.txt",
        Some("txt"),
        &options,
    )?
    .read_all()
}

fn read(text: &str) -> Result<Recording> {
    read_with(text.as_bytes(), ReadOptions::default())
}

fn tuples(rec: &Recording) -> Vec<(i64, u16, u16, u8)> {
    rec.events.iter().map(|e| (e.t, e.x, e.y, e.p)).collect()
}

#[test]
fn ecd_seconds_lines_convert_exactly() {
    let rec = read("0.003811000 96 133 0\n0.003820001 127 171 1\n1.000000500 0 0 1\n").unwrap();
    assert_eq!(
        tuples(&rec),
        vec![
            (3811, 96, 133, 0),
            (3820, 127, 171, 1),
            (1_000_001, 0, 0, 1)
        ]
    );
    assert!(rec.metadata.notes.iter().any(|n| n.contains("seconds")));
    assert!(!rec.report.has_problems());
}

#[test]
fn integer_lines_without_header_are_t_x_y_p_in_us() {
    let rec = read("10 1 2 1\n-20 3 4 0\n").unwrap();
    assert_eq!(tuples(&rec), vec![(10, 1, 2, 1), (-20, 3, 4, 0)]);
}

#[test]
fn metavision_csv_with_geometry_line() {
    let text = "%geometry:640,480\n10,20,1,5000\n639,479,0,5001\n640,0,1,5002\n3,4,0,5003\n";
    let rec = read(text).unwrap();
    assert_eq!(
        tuples(&rec),
        vec![(5000, 10, 20, 1), (5001, 639, 479, 0), (5003, 3, 4, 0)]
    );
    assert_eq!(rec.metadata.geometry, Some(Geometry::new(640, 480)));
    assert_eq!(rec.metadata.header_value("geometry"), Some("640,480"));
    assert_eq!(rec.report.out_of_range, 1);
}

#[test]
fn header_names_order_and_aliases() {
    let rec = read("x,y,polarity,timestamp\n1,2,1,100\n3,4,0,200\n").unwrap();
    assert_eq!(tuples(&rec), vec![(100, 1, 2, 1), (200, 3, 4, 0)]);
    // faery: t,x,y,on with booleans; an extra ignored column.
    let rec = read("t,x,y,on,extra\n5,1,1,true,zzz\n6,2,2,False,zzz\n").unwrap();
    assert_eq!(tuples(&rec), vec![(5, 1, 1, 1), (6, 2, 2, 0)]);
    // A unit in the header name.
    let rec = read("t[ms],x,y,p\n1.5,0,0,1\n2,0,0,1\n").unwrap();
    assert_eq!(rec.events.t, vec![1500, 2000]);
    let rec = read("time_s x y p\n2 0 0 1\n").unwrap();
    assert_eq!(rec.events.t, vec![2_000_000]);
    let err = read("a,b,c,d\n1,2,3,4\n").unwrap_err();
    assert!(matches!(err, Error::Parse { line: 1, .. }), "{err}");
}

#[test]
fn minus_one_polarity_tabs_comments_and_crlf() {
    let text = "\u{feff}# recorded 2024\r\n% another comment\r\n\r\n1\t5\t6\t-1\r\n2\t7\t8\t1\r\n  # indented comment\r\n3\t9\t10\t-1";
    let rec = read(text).unwrap();
    assert_eq!(
        tuples(&rec),
        vec![(1, 5, 6, 0), (2, 7, 8, 1), (3, 9, 10, 0)]
    );
    assert_eq!(
        rec.metadata.header_value("comment"),
        Some("# recorded 2024")
    );
}

#[test]
fn comment_line_can_name_the_columns() {
    let rec = read("# x y p t\n1 2 1 100\n").unwrap();
    assert_eq!(tuples(&rec), vec![(100, 1, 2, 1)]);
    // A comment that merely mentions the names does not.
    let rec = read("# columns: t x y p as usual\n100 1 2 1\n").unwrap();
    assert_eq!(tuples(&rec), vec![(100, 1, 2, 1)]);
}

#[test]
fn semicolons_with_decimal_commas() {
    let rec = read("0,5;1;2;1\n0,000001;3;4;0\n").unwrap();
    assert_eq!(tuples(&rec), vec![(500_000, 1, 2, 1), (1, 3, 4, 0)]);
}

#[test]
fn explicit_options_override_detection() {
    let options = ReadOptions {
        text: TextOptions {
            columns: Some(TextOptions::parse_columns("p _ t x y").unwrap()),
            delimiter: TextOptions::parse_delimiter("space").unwrap(),
            time_unit: TextOptions::parse_time_unit("ns").unwrap(),
            polarity: TextOptions::parse_polarity("-1,1").unwrap(),
        },
        geometry: Some(Geometry::new(10, 10)),
        ..Default::default()
    };
    let rec = read_with(b"1 junk 1500 3 4\n-1 junk 2499 9 9\n1 j 0 10 0\n", options).unwrap();
    assert_eq!(tuples(&rec), vec![(2, 3, 4, 1), (2, 9, 9, 0)]);
    assert_eq!(rec.report.out_of_range, 1);

    let options = ReadOptions {
        text: TextOptions {
            time_unit: TimeUnit::Scale(1000.0),
            ..Default::default()
        },
        ..Default::default()
    };
    let rec = read_with(b"1.5 0 0 1\n", options).unwrap();
    assert_eq!(rec.events.t, vec![1500]);
}

#[test]
fn strict_polarity_modes_reject_other_values() {
    let options = |p: &str| ReadOptions {
        text: TextOptions {
            polarity: PolarityEncoding::parse(p).unwrap(),
            ..Default::default()
        },
        ..Default::default()
    };
    let text = b"1 0 0 -1\n";
    assert!(read_with(text, options("0,1")).is_err());
    assert_eq!(read_with(text, options("-1,1")).unwrap().events.p, vec![0]);
    assert!(read_with(b"1 0 0 0\n", options("false,true")).is_err());
    assert!(read_with(b"1 0 0 2\n", options("auto")).is_err());
}

#[test]
fn out_of_range_coordinates_are_dropped_and_counted() {
    let rec = read("1 -1 0 1\n2 65536 0 1\n3 65535 65535 1\n4 1.0 2.000 0\n").unwrap();
    assert_eq!(tuples(&rec), vec![(3, 65535, 65535, 1), (4, 1, 2, 0)]);
    assert_eq!(rec.report.out_of_range, 2);
    assert_eq!(rec.report.malformed, 0);
}

#[test]
fn few_malformed_lines_warn_with_line_numbers() {
    let mut text = String::new();
    for i in 0..300 {
        text.push_str(&format!("{i} 1 2 1\n"));
    }
    text.push_str("oops 1 2 1\n");
    text.push_str("5 1 2\n");
    let rec = read(&text).unwrap();
    assert_eq!(rec.events.len(), 300);
    assert_eq!(rec.report.malformed, 2);
    let warning = rec.report.warnings.join("\n");
    assert!(
        warning.contains("line 301") && warning.contains("line 302"),
        "{warning}"
    );
}

#[test]
fn many_malformed_lines_are_an_error_naming_the_line() {
    let err = read("1 2 3 1\n2 2 3 1\nx y z w\n4 2 3 1\n").unwrap_err();
    match err {
        Error::Parse { line, message, .. } => {
            assert_eq!(line, 3);
            assert!(message.contains("1 of 4"), "{message}");
        }
        other => panic!("{other}"),
    }
    let err = read("1 2 3 1\n2 2.5 3 1\n").unwrap_err();
    assert!(err.to_string().contains("x is not an integer"), "{err}");
}

#[test]
fn empty_and_header_only_files() {
    assert!(read("").unwrap().events.is_empty());
    assert!(read("t,x,y,p\n").unwrap().events.is_empty());
    assert!(read("# nothing\n\n").unwrap().events.is_empty());
}

#[test]
fn batches_split_anywhere_give_the_same_events() {
    let mut text = String::new();
    for i in 0..120_000u32 {
        text.push_str(&format!(
            "{}.{:06} {} {} {}\r\n",
            i / 1000,
            (i % 1000) * 1000 + i % 7,
            i % 640,
            i % 480,
            i % 2
        ));
        if i % 5000 == 0 {
            text.push_str("# marker\n");
        }
    }
    let small = ReadOptions {
        batch_bytes: 1,
        ..Default::default()
    };
    let a = read_with(text.as_bytes(), small).unwrap();
    let b = read(&text).unwrap();
    assert_eq!(a.events.len(), 120_000);
    assert_eq!(a.events, b.events);
    assert_eq!(a.events.t[1234], 1_234_000 + 1234 % 7);
    assert!(!a.report.has_problems(), "{:?}", a.report);
}

#[test]
fn overlong_line_is_skipped_and_counted() {
    let mut text = String::new();
    for i in 0..200 {
        text.push_str(&format!("{i} 1 2 1\n"));
    }
    text.push_str(&"9".repeat(200_000));
    text.push('\n');
    for i in 0..200 {
        text.push_str(&format!("{i} 1 2 1\n"));
    }
    let options = ReadOptions {
        batch_bytes: 1,
        ..Default::default()
    };
    let rec = read_with(text.as_bytes(), options).unwrap();
    assert_eq!(rec.events.len(), 400);
    assert_eq!(rec.report.malformed, 1);
}

#[test]
fn option_parsers() {
    assert_eq!(
        TextOptions::parse_columns("t,x,y,p").unwrap(),
        vec![TextColumn::T, TextColumn::X, TextColumn::Y, TextColumn::P]
    );
    assert_eq!(
        TextOptions::parse_columns("x y pol ts _").unwrap(),
        vec![
            TextColumn::X,
            TextColumn::Y,
            TextColumn::P,
            TextColumn::T,
            TextColumn::Skip
        ]
    );
    assert!(TextOptions::parse_columns("t,x,y").is_err());
    assert!(TextOptions::parse_columns("t,x,x,y,p").is_err());
    assert!(TextOptions::parse_columns("t,x,y,q").is_err());
    assert_eq!(TimeUnit::parse("µs").unwrap(), TimeUnit::Microseconds);
    assert_eq!(TimeUnit::parse("S").unwrap(), TimeUnit::Seconds);
    assert_eq!(TimeUnit::parse("1e-3").unwrap(), TimeUnit::Scale(0.001));
    assert!(TimeUnit::parse("-1").is_err());
    assert!(TimeUnit::parse("fortnight").is_err());
    assert_eq!(
        "0,1".parse::<PolarityEncoding>().unwrap(),
        PolarityEncoding::ZeroOne
    );
    assert!(PolarityEncoding::parse("2,3").is_err());
    assert_eq!(TextOptions::parse_delimiter("tab").unwrap(), Some(b'\t'));
    assert_eq!(TextOptions::parse_delimiter("auto").unwrap(), None);
    assert!(TextOptions::parse_delimiter("|x").is_err());
}

proptest::proptest! {
    #[test]
    fn random_text_never_panics(bytes in proptest::collection::vec(proptest::num::u8::ANY, 0..3000)) {
        let _ = read_with(&bytes, ReadOptions::default());
    }

    #[test]
    fn random_numeric_lines_never_panic(lines in proptest::collection::vec("[-0-9.,;eE \t]{0,40}", 0..50)) {
        let text = lines.join("\n");
        let _ = read_with(text.as_bytes(), ReadOptions::default());
    }
}
