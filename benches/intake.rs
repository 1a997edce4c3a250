//! Intake of a long oscilloscope record: a 10⁷-sample, 4-channel Tektronix-layout CSV (RF,
//! MONITOR+, MONITOR−, TRIG; 440 samples per frame, 22 728 frames, values to 7 significant
//! digits as a scope writes them) read and cut into frames, against the baseline of reading
//! the file's lines without parsing them (the I/O floor) in the same run. Prints the time of
//! each, the file's size and the process's peak resident memory after the read, which should
//! follow the record's binary size (10⁷ × 4 × 8 bytes = 320 MB), not its text.
//!
//!     cargo bench --bench intake              (SPIBENCH_INTAKE_SAMPLES overrides 10⁷)
//!
//! Target on a 2-core machine: under 10 s for the read and the frames.

use std::io::{BufRead, Write};
use std::time::Instant;

use spibench::detector::{FrameTiming, SettleRule};
use spibench::intake::frames::{ChannelMap, find_frames};
use spibench::intake::record::read_csv;

fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb * 1024.0 / 1e6)
}

fn main() {
    let samples: usize = std::env::var("SPIBENCH_INTAKE_SAMPLES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000_000);
    let per_frame = 440;
    // Whole frames: 22 728 of them for 10⁷ (10 000 320 samples).
    let frames = samples.div_ceil(per_frame);
    let samples = frames * per_frame;
    let dir = std::env::temp_dir().join(format!("spibench-bench-intake-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("record.csv");
    let t0 = Instant::now();
    {
        let mut w =
            std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(&path).unwrap());
        write!(
            w,
            "Model,MSO64\nFirmware Version,2.0\n\nWaveform Type,ANALOG\nPoint Format,Y\n\
             Horizontal Units,s\nSample Interval,1e-07\nRecord Length,{samples}\n\
             Vertical Units,V,V,V,V\nVertical Offset,0,0,0,0\nVertical Scale,0.05,0.005,0.005,1\n\
             Zero Index,0\nLabel,RF,MON+,MON-,TRIG\nTIME,CH1,CH2,CH3,CH4\n"
        )
        .unwrap();
        let mut x: u64 = 1;
        for n in 0..samples {
            let f = n / per_frame;
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let noise = ((x >> 40) as f64 / (1u64 << 24) as f64 - 0.5) * 1e-4;
            let level = ((f * 7919) % 97) as f64 / 97.0;
            let trig = if n % per_frame < per_frame / 4 {
                3.3
            } else {
                0.0
            };
            writeln!(
                w,
                "{:.7e},{:.6e},{:.6e},{:.6e},{}",
                n as f64 * 1e-7,
                0.1 * (2.0 * level - 1.0) + noise,
                0.01 * level + 0.001 + noise,
                0.01 * (1.0 - level) + 0.001 - noise,
                trig
            )
            .unwrap();
        }
    }
    let bytes = std::fs::metadata(&path).unwrap().len();
    println!(
        "wrote {samples} samples × 4 channels, {:.0} MB of CSV, in {:.1} s",
        bytes as f64 / 1e6,
        t0.elapsed().as_secs_f64()
    );

    let t = Instant::now();
    let file = std::fs::File::open(&path).unwrap();
    let lines = std::io::BufReader::with_capacity(1 << 20, file)
        .lines()
        .count();
    let floor_s = t.elapsed().as_secs_f64();
    println!("baseline, the lines read without parsing: {lines} lines in {floor_s:.2} s");

    let rss0 = peak_rss_mb();
    let t = Instant::now();
    let rec = read_csv(&path).unwrap();
    let read_s = t.elapsed().as_secs_f64();
    let rss = peak_rss_mb();
    let rule = SettleRule::of(FrameTiming {
        frame_s: 44e-6,
        settling_s: 13e-6,
        sample_rate_hz: 1e7,
    });
    let map = ChannelMap {
        signals: [0, 1, 2],
        trigger: Some(3),
    };
    let t = Instant::now();
    let found = find_frames(&rec, &map, &rule, frames, 0).unwrap();
    let frames_s = t.elapsed().as_secs_f64();
    assert_eq!(found.frames.len(), frames);
    println!(
        "intake: read {:.2} s ({:.1} × the baseline), frames {:.2} s, total {:.2} s; peak \
         resident memory {:.0} MB before the read, {:.0} MB after (binary size of the record \
         {:.0} MB, text {:.0} MB)",
        read_s,
        read_s / floor_s,
        frames_s,
        read_s + frames_s,
        rss0,
        rss,
        (samples * 4 * 8) as f64 / 1e6,
        bytes as f64 / 1e6
    );
    let _ = std::fs::remove_dir_all(&dir);
}
