//! The CSV layouts and every located error of a CSV record.

use super::*;

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn tmp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("spibench-intake-{name}-{}", std::process::id()))
}

const TEK: &str = "Model,MSO64\nFirmware Version,1.0\n\nWaveform Type,ANALOG\nPoint Format,Y\n\
Horizontal Units,s\nSample Interval,1e-07\nRecord Length,3\nVertical Units,V,V\n\
Vertical Offset,0.5,0\nVertical Scale,0.1,1\nZero Index,1\nLabel,RF,\nTIME,CH1,CH2\n\
-1e-07,0.25,1\n0,0.5,2\n1e-07,0.75,3\n";

#[test]
fn the_three_layouts_read_the_same_samples() {
    let d = tmp("layouts");
    let tek = read_csv(&write(&d, "tek.csv", TEK.as_bytes())).unwrap();
    assert_eq!(tek.layout, Layout::Tektronix);
    assert_eq!(tek.sample_interval_s, 1e-7);
    assert_eq!(tek.trigger_index, Some(1));
    assert_eq!(tek.data, vec![vec![0.25, 0.5, 0.75], vec![1.0, 2.0, 3.0]]);
    assert_eq!(tek.channel("rf"), Some(0));
    assert_eq!(tek.channel("CH2"), Some(1));
    assert_eq!(tek.screens[0].unwrap().window(), (0.0, 1.0));
    let ks = "x-axis,1,2\nsecond,Volt,Volt\n-1e-07,0.25,1\n0,0.5,2\n1e-07,0.75,3\n";
    let ks = read_csv(&write(&d, "ks.csv", ks.as_bytes())).unwrap();
    assert_eq!(ks.layout, Layout::Keysight);
    assert_eq!(ks.columns, vec!["CH1", "CH2"]);
    assert!((ks.sample_interval_s - 1e-7).abs() < 1e-20);
    assert_eq!(ks.trigger_index, Some(1));
    assert_eq!(ks.data, tek.data);
    let rg = "X,CH1,CH2,Start,Increment,\nSequence,Volt,Volt,-1e-07,1e-07\n0,0.25,1,\n1,0.5,2,\n\
              2,0.75,3,\n";
    let rg = read_csv(&write(&d, "rg.csv", rg.as_bytes())).unwrap();
    assert_eq!(rg.layout, Layout::Rigol);
    assert_eq!((rg.sample_interval_s, rg.trigger_index), (1e-7, Some(1)));
    assert_eq!(rg.data, tek.data);
    let screen = "Time(s),CH1(V),CH2(V)\n-1e-07,0.25,1\n0,0.5,2\n1e-07,0.75,3\n";
    let sc = read_csv(&write(&d, "sc.csv", screen.as_bytes())).unwrap();
    assert_eq!(
        (sc.layout, sc.columns.clone()),
        (Layout::Rigol, vec!["CH1".into(), "CH2".into()])
    );
    assert_eq!(sc.data, tek.data);
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn a_bom_and_crlf_line_ends_read_as_plain_text() {
    let d = tmp("bom");
    let mut bytes = vec![0xEF, 0xBB, 0xBF];
    bytes.extend(TEK.replace('\n', "\r\n").as_bytes());
    let r = read_csv(&write(&d, "bom.csv", &bytes)).unwrap();
    assert_eq!(r.layout, Layout::Tektronix);
    assert_eq!(r.data[1], vec![1.0, 2.0, 3.0]);
    let _ = std::fs::remove_dir_all(&d);
}

/// The error of a damaged copy of TEK: input, naming the file and `line N`.
fn damaged(name: &str, text: &str, line: usize, says: &str) {
    let d = tmp(name);
    let p = write(&d, "bad.csv", text.as_bytes());
    let e = read_csv(&p).unwrap_err();
    let m = e.to_string();
    assert!(e.is_user_error(), "{m}");
    assert!(
        m.contains("bad.csv") && m.contains(&format!("line {line}")),
        "{name}: {m}"
    );
    assert!(m.contains(says), "{name}: {m}");
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn damaged_records_are_located_errors() {
    // Lines: 15 is the first sample, 17 the last.
    damaged("truncated", &TEK[..TEK.len() - 3], 17, "cut short");
    damaged("truncated-cell", &TEK[..TEK.len() - 2], 17, "cut short");
    damaged(
        "nan",
        &TEK.replace("0,0.5,2", "0,NaN,2"),
        16,
        "not a finite number",
    );
    damaged("empty", &TEK.replace("0,0.5,2", "0,,2"), 16, "empty cell");
    damaged(
        "few",
        &TEK.replace("0,0.5,2", "0,0.5"),
        16,
        "2 cells where the header names 3",
    );
    damaged(
        "many",
        &TEK.replace("0,0.5,2", "0,0.5,2,7"),
        16,
        "more cells",
    );
    damaged(
        "length",
        &TEK.replace("Record Length,3", "Record Length,4"),
        17,
        "Record Length",
    );
    damaged("layout", "hello,world\n1,2\n", 1, "unknown CSV layout");
}
