use super::header::PierSide;
use super::*;

const HEAD: &str = "Guiding Begins at 2017-03-10 20:22:52\nExposure = 2000 ms\n\
    Frame,Time,mount,dx,dy,RARawDistance,DECRawDistance,RAGuideDistance,DECGuideDistance,\
    RADuration,RADirection,DECDuration,DECDirection,XStep,YStep,StarMass,SNR,ErrorCode\n";
const ROW1: &str =
    "1,2.250,\"Mount\",0.856,-0.494,-0.899,-0.308,-0.540,0.000,227,E,0,,,,1762,23.05,0\n";
const ROW2: &str =
    "2,4.109,\"Mount\",0.159,-0.340,-0.191,-0.300,-0.115,0.000,48,E,0,,,,1463,21.04,0\n";
const DROP: &str = "3,3.2,\"DROP\",,,,,,,,,,,,,1486,21.65,6,\"Star lost, mass changed\"\n";

fn p(text: &str) -> Result<GuideLog, Error> {
    parse(text, Path::new("x.txt"))
}

#[test]
fn parses_frames_dithers_and_exposure() {
    let text = format!("{HEAD}{ROW1}INFO: SETTLING STATE CHANGE, Settling started\n{DROP}INFO: DITHER by -4.987, 0.636, new lock pos = 636.680, 509.874\n{ROW2}");
    let log = p(&text).unwrap();
    assert_eq!(log.sections.len(), 1);
    let s = &log.sections[0];
    assert_eq!(
        (s.line, s.rows_line, s.start_s, s.exposure_s),
        (1, 3, 0.0, 2.0)
    );
    assert_eq!(s.frames.len(), 2);
    let f = &s.frames[0];
    assert_eq!(
        (
            f.line,
            f.frame,
            f.time_s,
            f.ra_raw,
            f.ra_guide,
            f.ra_applied,
            f.snr
        ),
        (4, 1, 2.25, -0.899, -0.540, -0.540, 23.05)
    );
    assert_eq!(s.frames[1].line, 8);
    assert_eq!(
        s.events,
        vec![
            Event {
                line: 5,
                next_frame: 1,
                kind: EventKind::SettlingStarted
            },
            Event {
                line: 6,
                next_frame: 1,
                kind: EventKind::Drop { time_s: 3.2 }
            },
            Event {
                line: 7,
                next_frame: 1,
                kind: EventKind::Dither {
                    x: -4.987,
                    y: 0.636
                }
            },
        ]
    );
    assert_eq!(s.dithers().collect::<Vec<_>>(), vec![(1, -4.987, 0.636)]);
    assert_eq!(s.drops().collect::<Vec<_>>(), vec![(1, 3.2)]);
    assert_eq!(log.name(), "x");
    assert_eq!(log.frame_count(), 2);
}

/// A night: two sections with their own headers, a calibration between
/// them, the second section left open at the end of the file.
#[test]
fn sections_with_their_own_headers_on_the_nights_clock() {
    let second = "Guiding Begins at 2017-03-10 21:00:00\nPixel scale = 1.5 arc-sec/px\n\
        Exposure = 3000 ms\nMount = M, connected, xRate = 0.5, yRate = 1\n\
        X guide algorithm = Predictive PEC, Control gain = 0.6\n\
        RA = 5.51 hr, Dec = 34.4 deg, Hour angle = -2.46 hr, Pier side = East\n";
    let calibration = "Calibration Begins at 2017-03-10 20:50:00\nExposure = 300 ms\n\
        Direction,Step,dx,dy,x,y,Dist\nWest,0,0.000,0.000,2164.319,117.673,0.000\n\
        1,2.0,\"Mount\",0,0,99,0,99,0,0,,0,,,,1,1,0\n\
        Calibration complete, mount = M.\n";
    let text = format!(
        "{HEAD}{ROW1}{ROW2}Guiding Ends at 2017-03-10 20:23:00\n\n{calibration}{second}{}{}{}",
        HEAD.lines().nth(2).unwrap().to_string() + "\n",
        ROW1.replace("-0.540", "1.026").replace(",227,", ",1500,"),
        ROW2
    );
    let log = p(&text).unwrap();
    assert_eq!(log.sections.len(), 2);
    let (a, b) = (&log.sections[0], &log.sections[1]);
    assert_eq!(
        (a.exposure_s, a.start_s, a.header.pixel_scale),
        (2.0, 0.0, None)
    );
    assert_eq!(b.line, 14);
    assert_eq!(b.start_s, 37.0 * 60.0 + 8.0);
    assert_eq!((b.exposure_s, b.header.pixel_scale), (3.0, Some(1.5)));
    assert_eq!(b.header.x_rate, Some(0.5));
    assert!(b.header.predictive() && !a.header.predictive());
    assert_eq!(b.header.pointing.pier_side, Some(PierSide::East));
    assert_eq!(b.header.pointing.hour_angle_hr, Some(-2.46));
    // 1.026 px asked for, a 1.5 s pulse at 0.5 px/s sent.
    assert_eq!(b.frames[0].ra_guide, 1.026);
    assert_eq!(b.frames[0].ra_applied, 0.75);
    assert_eq!(b.end_s(), b.start_s + 4.109);
}

#[test]
fn a_section_begins_no_earlier_than_the_last_ended() {
    let text = format!(
        "{HEAD}{ROW1}{ROW2}{}{ROW1}{ROW2}",
        HEAD.replace("20:22:52", "20:22:50")
    );
    let log = p(&text).unwrap();
    assert_eq!(log.sections[1].start_s, 4.109);
    assert_eq!(log.sections[1].exposure_s, 2.0);
}

#[test]
fn a_frame_header_without_a_begin_starts_a_section() {
    let rows = HEAD.lines().nth(2).unwrap();
    let text = format!("Exposure = 2000 ms\n{rows}\n{ROW1}{ROW2}{rows}\n{ROW1}");
    let log = p(&text).unwrap();
    assert_eq!(log.sections.len(), 2);
    assert_eq!((log.sections[0].line, log.sections[0].start_s), (2, 0.0));
    let b = &log.sections[1];
    assert_eq!((b.line, b.start_s, b.exposure_s), (5, 4.109, 2.0));
}

#[test]
fn error_bad_number() {
    let text = format!("{HEAD}{ROW1}{}", ROW2.replace("-0.191", "-0.1x1"));
    assert_eq!(
        p(&text).unwrap_err().to_string(),
        "x.txt:5: RARawDistance: not a finite number: \"-0.1x1\""
    );
    let text = format!("{HEAD}{}", ROW1.replace("23.05", "nan"));
    assert_eq!(p(&text).unwrap_err().line, Some(4));
    let text = format!("{HEAD}{}", ROW1.replace("-0.540", ""));
    assert!(p(&text)
        .unwrap_err()
        .to_string()
        .starts_with("x.txt:4: RAGuideDistance"));
    let text = format!("{HEAD}{}", ROW1.replace(",227,", ",-3,"));
    assert!(p(&text)
        .unwrap_err()
        .to_string()
        .starts_with("x.txt:4: RADuration"));
}

#[test]
fn error_short_row() {
    let text = format!("{HEAD}1,2.250,\"Mount\",0.856,-0.494,-0.899,-0.308,-0.540\n");
    let e = p(&text).unwrap_err();
    assert_eq!(e.line, Some(4));
    assert!(e.message.contains("no SNR column"), "{e}");
}

#[test]
fn error_missing_columns() {
    let text = "Exposure = 2000 ms\nFrame,Time,mount,dx,dy,RAGuideDistance\n";
    assert_eq!(
        p(text).unwrap_err().to_string(),
        "x.txt:2: guide-frame header lacks column(s) RARawDistance, SNR"
    );
}

#[test]
fn error_no_rows() {
    let text = format!("{HEAD}{DROP}");
    assert_eq!(
        p(&text).unwrap_err().to_string(),
        "x.txt:3: no guide frames (rows with a frame number and RARawDistance)"
    );
    assert_eq!(
        p("hello\n").unwrap_err().to_string(),
        "x.txt: no `Frame,Time,...` guide-frame header"
    );
}

#[test]
fn error_row_outside_a_section() {
    let e = p(&format!("Exposure = 2000 ms\n{ROW1}")).unwrap_err();
    assert_eq!(e.line, Some(2));
    let e = p(&format!(
        "{HEAD}{ROW1}Guiding Ends at 2017-03-10 20:23:00\n{ROW2}"
    ))
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "x.txt:6: guide-frame row outside a guiding section"
    );
}

#[test]
fn error_exposure() {
    let e = p(&format!("{}{ROW1}", HEAD.replace("2000 ms", "2 s"))).unwrap_err();
    assert_eq!(e.line, Some(2));
    let e = p(&format!(
        "{}{ROW1}",
        HEAD.replace("Exposure = 2000 ms\n", "")
    ))
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "x.txt:2: guiding section without an `Exposure = N ms` header line"
    );
}

#[test]
fn error_begins() {
    let e = p(&format!("{}{ROW1}", HEAD.replace("20:22:52", "25:22:52"))).unwrap_err();
    assert_eq!(
        e.to_string(),
        "x.txt:1: Guiding Begins at: \"2017-03-10 25:22:52\" is not `YYYY-MM-DD HH:MM:SS`"
    );
}

#[test]
fn error_dither() {
    let e = p(&format!(
        "{HEAD}{ROW1}INFO: DITHER by abc, 1.0, new lock pos = 1, 2\n{ROW2}"
    ))
    .unwrap_err();
    assert_eq!(
        e.to_string(),
        "x.txt:5: DITHER x: not a finite number: \"abc\""
    );
}
