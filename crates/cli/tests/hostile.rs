//! Hostile input, end to end: the reproducers of issue 15 and a campaign of mutated inputs over
//! every input type and command.
//!
//! Every case runs the binary under a 2 GB address-space limit and a 60 s timeout, and must end
//! with exit 0, or exit 2 with nothing on standard output and one line on standard error that
//! names the input. A panic (101), an abort on allocation (134), a hang or exit 1 fails.
//!
//! The campaign is deterministic (seeded). `EVIGRID_CAMPAIGN_CASES` sets its size (default 160,
//! a few seconds; the long campaign of the issue note ran 2 000).

#![allow(clippy::unwrap_used)]

use std::fs;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use fuzz::mutate::{Rng, mutate};

const MEMORY_LIMIT_KB: u64 = 2_000_000;
const TIMEOUT: Duration = Duration::from_secs(60);

/// How one case ended.
#[derive(Debug)]
struct Outcome {
    code: Option<i32>,
    stdout: String,
    stderr: String,
    took: Duration,
}

/// Runs `evigrid args…` in `dir` under the memory limit and timeout.
fn run_limited(dir: &Path, args: &[&str]) -> Outcome {
    run_limited_with(dir, args, false)
}

/// [`run_limited`], with standard output a pipe whose reader has left if `closed_stdout`.
fn run_limited_with(dir: &Path, args: &[&str], closed_stdout: bool) -> Outcome {
    let mut command = Command::new("sh");
    command
        .arg("-c")
        .arg(format!("ulimit -v {MEMORY_LIMIT_KB}; exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .current_dir(dir)
        .env("EVIGRID_SHARED", "/nonexistent")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let started = Instant::now();
    let mut child = command.spawn().unwrap();
    if closed_stdout {
        drop(child.stdout.take());
    }
    loop {
        if let Some(_status) = child.try_wait().unwrap() {
            break;
        }
        if started.elapsed() > TIMEOUT {
            let _ = child.kill();
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let took = started.elapsed();
    let output = child.wait_with_output().unwrap();
    Outcome {
        code: if took > TIMEOUT {
            None
        } else {
            output.status.code()
        },
        stdout: String::from_utf8_lossy(&output.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
        took,
    }
}

/// The promise of issue 15; `None` if kept, else what broke.
fn broken_promise(outcome: &Outcome) -> Option<String> {
    broken_promise_in(outcome, false)
}

/// The promise of issues 15 and 31: with `environment` (a full disk), exit 1 with one line is
/// kept too.
fn broken_promise_in(outcome: &Outcome, environment: bool) -> Option<String> {
    match outcome.code {
        Some(0) => None,
        Some(1) if environment => {
            let lines: Vec<&str> = outcome.stderr.lines().collect();
            if lines.len() == 1 && lines[0].starts_with("evigrid: ") {
                None
            } else {
                Some(format!(
                    "exit 1 without one `evigrid:` line: {:?}",
                    outcome.stderr
                ))
            }
        }
        Some(2) => {
            let lines: Vec<&str> = outcome.stderr.lines().collect();
            if !outcome.stdout.is_empty() {
                Some(format!("exit 2 with standard output {:?}", outcome.stdout))
            } else if lines.len() != 1 || !lines[0].starts_with("evigrid: ") {
                Some(format!(
                    "exit 2 without one `evigrid:` line: {:?}",
                    outcome.stderr
                ))
            } else {
                None
            }
        }
        Some(code) => Some(format!("exit {code}: {}", outcome.stderr.trim())),
        None => Some(format!(
            "no answer after {:.0} s",
            outcome.took.as_secs_f64()
        )),
    }
}

fn assert_bad_input(dir: &Path, args: &[&str], expected: &str) {
    let outcome = run_limited(dir, args);
    assert_eq!(outcome.code, Some(2), "{args:?}: {outcome:?}");
    assert!(broken_promise(&outcome).is_none(), "{args:?}: {outcome:?}");
    assert!(
        outcome.stderr.contains(expected),
        "{args:?}: expected {expected:?} in {:?}",
        outcome.stderr
    );
}

fn pcd(header_lines: &str, data: &str) -> String {
    format!(
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n\
         {header_lines}\nVIEWPOINT 0 0 0 1 0 0 0\nDATA {data}"
    )
}

/// A folder `name` with one scan `a.pcd` holding `content`.
fn scans(dir: &Path, name: &str, content: &[u8]) -> String {
    fs::create_dir_all(dir.join(name)).unwrap();
    fs::write(dir.join(name).join("a.pcd"), content).unwrap();
    name.to_string()
}

#[test]
fn the_reproducers_of_issue_15_are_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    fs::write(d.join("p.txt"), "0 0 0 0 0 0 0\n").unwrap();
    let anti = r#"{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"building":"yes"},"geometry":{"type":"Polygon","coordinates":[[[179.999,0],[-179.999,0],[-179.999,0.001],[179.999,0.001],[179.999,0]]]}}]}"#;
    fs::write(d.join("anti.geojson"), anti).unwrap();
    let headers = [
        (
            "points-4e9",
            "WIDTH 1\nHEIGHT 1\nPOINTS 4000000000",
            "ascii\n1 2 3\n",
        ),
        (
            "points-max",
            "WIDTH 1\nHEIGHT 1\nPOINTS 18446744073709551615",
            "ascii\n1 2 3\n",
        ),
        (
            "wh-4e9",
            "WIDTH 4000000000\nHEIGHT 4000000000",
            "ascii\n1 2 3\n",
        ),
        (
            "points-disagree",
            "WIDTH 2\nHEIGHT 1\nPOINTS 2",
            "ascii\n1 2 3\n",
        ),
    ];
    for (name, header, data) in headers {
        let s = scans(d, name, pcd(header, data).as_bytes());
        assert_bad_input(
            d,
            &["run", "--scans", &s, "--poses", "p.txt", "--out", "o"],
            "a.pcd",
        );
        let scan = format!("{s}/a.pcd");
        assert_bad_input(
            d,
            &[
                "bench",
                "--scan",
                &scan,
                "--map",
                "anti.geojson",
                "--sizes",
                "64",
            ],
            "a.pcd",
        );
    }
    let huge_size = pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "binary\n0123456789ab")
        .replace("SIZE 4 4 4", "SIZE 4 4 18446744073709551612");
    let s = scans(d, "size", huge_size.as_bytes());
    assert_bad_input(
        d,
        &["run", "--scans", &s, "--poses", "p.txt", "--out", "o"],
        "a.pcd",
    );
    let huge_count = pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "ascii\n1 2 3\n")
        .replace("COUNT 1 1 1", "COUNT 1 1 1000000000000");
    let s = scans(d, "count", huge_count.as_bytes());
    assert_bad_input(
        d,
        &["run", "--scans", &s, "--poses", "p.txt", "--out", "o"],
        "a.pcd",
    );

    // Sizes from the command line and from parameter files.
    for (w, h) in [("4294967296", "1"), ("100000", "100000"), ("5000", "5000")] {
        fs::write(
            d.join("w.toml"),
            format!("[window]\nwidth_cells = {w}\nheight_cells = {h}\n"),
        )
        .unwrap();
        assert_bad_input(
            d,
            &[
                "run", "--scans", "count", "--poses", "p.txt", "--out", "o", "--config", "w.toml",
            ],
            "memory budget",
        );
    }
    assert_bad_input(d, &["cell", "--observe", "free*1000000000000"], "--observe");
    assert_bad_input(
        d,
        &["bench", "--sizes", "4294967296", "--synthetic-only"],
        "--sizes",
    );
    for seeds in ["18446744073709551615", "1001"] {
        assert_bad_input(
            d,
            &[
                "eval",
                "--map",
                "m",
                "--scenario",
                "s",
                "--out",
                "o",
                "--seeds",
                seeds,
            ],
            "--seeds",
        );
    }

    // Maps: the world, the antimeridian, a gzip bomb, special files.
    let world = r#"{"type":"FeatureCollection","features":[{"type":"Feature","properties":{"highway":"primary"},"geometry":{"type":"LineString","coordinates":[[-179,-85],[179,85]]}}]}"#;
    fs::write(d.join("world.geojson"), world).unwrap();
    fs::write(d.join("s.toml"), "duration_s = 0.2\n").unwrap();
    assert_bad_input(
        d,
        &[
            "eval",
            "--map",
            "world.geojson",
            "--scenario",
            "s.toml",
            "--out",
            "oe",
            "--seeds",
            "1",
        ],
        "at most 50000 m across",
    );
    assert_bad_input(
        d,
        &["map", "render", "world.geojson", "--out", "w.png"],
        "--cell",
    );
    let rendered = run_limited(d, &["map", "render", "anti.geojson", "--out", "anti.png"]);
    assert_eq!(rendered.code, Some(0), "{rendered:?}");
    let info = run_limited(d, &["map", "info", "anti.geojson", "--json"]);
    assert_eq!(info.code, Some(0), "{info:?}");
    let info: serde_json::Value = serde_json::from_str(&info.stdout).unwrap();
    // A 0.002° box across the antimeridian is 223 m wide, not the whole equator.
    assert!(
        info["extent_m"]["width_m"].as_f64().unwrap() < 300.0,
        "{info}"
    );

    let mut bomb = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    std::io::Write::write_all(&mut bomb, b"<?xml version=\"1.0\"?><osm version=\"0.6\">").unwrap();
    let spaces = vec![b' '; 1 << 20];
    for _ in 0..600 {
        std::io::Write::write_all(&mut bomb, &spaces).unwrap();
    }
    fs::write(d.join("bomb.osm.gz"), bomb.finish().unwrap()).unwrap();
    assert_bad_input(
        d,
        &["map", "info", "bomb.osm.gz"],
        "decompressed map is larger",
    );
    assert_bad_input(d, &["map", "info", "/dev/zero"], "not a regular file");
    let fifo = d.join("fifo");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if made.is_ok_and(|s| s.success()) {
        assert_bad_input(d, &["map", "info", "fifo"], "not a regular file");
        assert_bad_input(
            d,
            &["cell", "--observe", "free", "--config", "fifo"],
            "not a regular file",
        );
        assert_bad_input(
            d,
            &["bench", "--scan", "fifo", "--map", "anti.geojson"],
            "fifo",
        );
    }

    // Scenarios that would run forever.
    for (text, what) in [
        ("duration_s = 1e9\n", "frames"),
        ("[sensor]\nrate_hz = 1e6\n", "frames"),
        ("[traffic]\nmoving_cars = 1000000000\n", "moving_cars"),
        ("[ego]\nwaypoints = [[0.0, 0.0, 5.0]]\n", "3 values"),
    ] {
        fs::write(d.join("bad.toml"), text).unwrap();
        assert_bad_input(
            d,
            &[
                "eval",
                "--map",
                "anti.geojson",
                "--scenario",
                "bad.toml",
                "--out",
                "ob",
            ],
            what,
        );
    }

    // Outputs: never an input, never a special file, never someone else's folder.
    assert_bad_input(
        d,
        &[
            "map",
            "crop",
            "anti.geojson",
            "--bbox",
            "0,179.99,0.001,179.999",
            "--out",
            "anti.geojson",
        ],
        "is the input",
    );
    assert_bad_input(
        d,
        &["map", "render", "anti.geojson", "--out", "/dev/full"],
        "not a regular file",
    );
    fs::create_dir_all(d.join("mine")).unwrap();
    fs::write(d.join("mine/thesis.tex"), "precious").unwrap();
    assert_bad_input(
        d,
        &["demo", "--frames", "1", "--out", "mine"],
        "not an evigrid output folder",
    );
    assert_bad_input(
        d,
        &["demo", "--frames", "1", "--out", "p.txt"],
        "not a folder",
    );
    assert_eq!(
        fs::read_to_string(d.join("mine/thesis.tex")).unwrap(),
        "precious"
    );
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(ToString::to_string).collect()
}

/// Seeds of the campaign: one valid input per input type, and the command that reads it.
struct Family {
    name: &'static str,
    file: &'static str,
    seeds: Vec<Vec<u8>>,
    args: fn(&str) -> Vec<String>,
    /// The environment may fail (a full disk): exit 1 with one line is a kept promise.
    environment: bool,
}

/// Where the campaign's odometry cases write: new files, their inputs (also through links),
/// a user's file, a device; with or without `--force`. None but the first may be written.
const ODOMETRY_OUTS: [&str; 7] = [
    "os.txt",
    "os/b.pcd",
    "os-link.pcd",
    "os-hard.pcd",
    "os-times.txt",
    "user.txt",
    "/dev/null",
];

fn families() -> Vec<Family> {
    let scan_seed = pcd(
        "WIDTH 3\nHEIGHT 1\nPOINTS 3",
        "ascii\n5 1 0.5\n7 -2 1\n12 0 -1.7\n",
    );
    let target_seeds = |name: &str| (fuzz::target(name).unwrap().seeds)();
    vec![
        Family {
            name: "pcd",
            file: "scans/a.pcd",
            seeds: vec![scan_seed.into_bytes()],
            args: |_| {
                strings(&["run", "--scans", "scans", "--poses", "p.txt", "--out", "out"])
            },
            environment: false,
        },
        Family {
            name: "poses",
            file: "poses.txt",
            seeds: target_seeds("poses"),
            args: |f| {
                vec![
                    "run".into(),
                    "--scans".into(),
                    "good".into(),
                    "--poses".into(),
                    f.into(),
                    "--out".into(),
                    "out".into(),
                ]
            },
            environment: false,
        },
        Family {
            name: "params",
            file: "params.toml",
            seeds: target_seeds("params"),
            args: |f| strings(&["cell", "--observe", "free*3,occupied", "--config", f]),
            environment: false,
        },
        Family {
            name: "map",
            file: "map.osm",
            seeds: target_seeds("map"),
            args: |f| strings(&["map", "info", f]),
            environment: false,
        },
        Family {
            name: "map-render",
            file: "map.geojson",
            seeds: target_seeds("map"),
            args: |f| strings(&["map", "render", f, "--out", "out.png", "--cell", "2"]),
            environment: false,
        },
        Family {
            name: "mass",
            file: "m.json",
            seeds: vec![
                br#"{"frame": ["a", "b", "c"], "mass": [{"set": ["a"], "m": 0.6}, {"set": ["a", "b"], "m": 0.3}, {"set": ["a", "b", "c"], "m": 0.1}]}"#.to_vec(),
            ],
            args: |f| strings(&["mass", "combine", "--rule", "dempster", f, f]),
            environment: false,
        },
        Family {
            name: "odometry",
            file: "os/a.pcd",
            seeds: vec![corner_pcd(0.0).into_bytes()],
            // The --out is added per case, from ODOMETRY_OUTS.
            args: |_| strings(&["odometry", "os", "--times", "os-times.txt"]),
            environment: false,
        },
        Family {
            name: "full-disk",
            file: "fd/a.pcd",
            seeds: vec![corner_pcd(0.0).into_bytes()],
            args: |_| strings(&["odometry", "fd", "--out", "full/p.txt", "--force"]),
            environment: true,
        },
    ]
}

#[test]
fn a_campaign_of_mutated_inputs_keeps_the_promise() {
    let cases: usize = std::env::var("EVIGRID_CAMPAIGN_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(160);
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    fs::create_dir_all(d.join("scans")).unwrap();
    fs::create_dir_all(d.join("good")).unwrap();
    fs::write(
        d.join("good/a.pcd"),
        pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "ascii\n5 1 0.5\n"),
    )
    .unwrap();
    fs::write(d.join("p.txt"), "0 0 0 0 0 0 0\n").unwrap();
    // The odometry's inputs and a user's file, none of which a case may change.
    for folder in ["os", "fd"] {
        fs::create_dir_all(d.join(folder)).unwrap();
        fs::write(d.join(folder).join("b.pcd"), corner_pcd(0.3)).unwrap();
        fs::write(d.join(folder).join("c.pcd"), corner_pcd(0.6)).unwrap();
    }
    fs::write(d.join("os-times.txt"), "0\n0.1\n0.2\n").unwrap();
    std::os::unix::fs::symlink(d.join("os/b.pcd"), d.join("os-link.pcd")).unwrap();
    fs::hard_link(d.join("os/c.pcd"), d.join("os-hard.pcd")).unwrap();
    fs::write(d.join("user.txt"), "a user's notes").unwrap();
    let protected = ["os/b.pcd", "os/c.pcd", "os-times.txt", "user.txt"];
    let kept: Vec<Vec<u8>> = protected
        .iter()
        .map(|f| fs::read(d.join(f)).unwrap())
        .collect();
    // A full disk where this test may mount one.
    let disk = FullDisk::mount(d);
    if let Some(disk) = &disk {
        disk.fill(0);
    }
    let families: Vec<Family> = families()
        .into_iter()
        .filter(|f| disk.is_some() || !f.environment)
        .collect();
    let mut rng = Rng::new(15);
    let mut failures = Vec::new();
    // Per family: cases, exit 0 (the mutant was still valid), exit 2 (refused), closed pipes.
    let mut per_family = vec![[0usize; 4]; families.len()];
    for case in 0..cases {
        let k = case % families.len();
        let family = &families[k];
        let base = &family.seeds[rng.below(family.seeds.len())];
        let other = &family.seeds[rng.below(family.seeds.len())];
        let input = mutate(&mut rng, base, other, 1 << 14);
        fs::write(d.join(family.file), &input).unwrap();
        let mut args = (family.args)(family.file);
        if family.name == "odometry" {
            let out = ODOMETRY_OUTS[rng.below(ODOMETRY_OUTS.len())];
            args.extend(strings(&["--out", out]));
            if rng.below(2) == 0 {
                args.push("--force".into());
            }
            if rng.below(2) == 0 {
                args.extend(strings(&["--format", "kitti"]));
            }
        }
        // One case in four: standard output closed by its reader (`| head -c 0`).
        let closed_stdout = rng.below(4) == 0;
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let outcome = run_limited_with(d, &args, closed_stdout);
        per_family[k][0] += 1;
        match outcome.code {
            Some(0) => per_family[k][1] += 1,
            Some(2) => per_family[k][2] += 1,
            _ => {}
        }
        if closed_stdout {
            per_family[k][3] += 1;
        }
        let mut problem = broken_promise_in(&outcome, family.environment);
        if fs::read(d.join(family.file)).ok().as_ref() != Some(&input) {
            problem = Some(format!("the input {} was changed", family.file));
        }
        // A user's file named with --force is the user's choice to replace it.
        let replaced =
            |file: &str| args.windows(2).any(|w| w == ["--out", file]) && args.contains(&"--force");
        for (file, bytes) in protected.iter().zip(&kept) {
            if fs::read(d.join(file)).ok().as_ref() != Some(bytes) {
                if !(*file == "user.txt" && replaced(file)) {
                    problem = Some(format!("{file} was overwritten"));
                }
                fs::write(d.join(file), bytes).unwrap();
            }
        }
        if !temporaries(d).is_empty() {
            problem = Some(format!("temporaries left: {:?}", temporaries(d)));
            for left in temporaries(d) {
                let _ = fs::remove_file(left);
            }
        }
        if let Some(problem) = problem {
            let kept = d.join(format!("failure-{case}-{}", family.name));
            fs::write(&kept, &input).unwrap();
            failures.push(format!(
                "{} case {case} ({args:?}, closed stdout {closed_stdout}): {problem}\n  input: {:?}",
                family.name,
                String::from_utf8_lossy(&input)
            ));
        }
    }
    for (family, [n, ok, refused, closed]) in families.iter().zip(&per_family) {
        println!(
            "{:<11} {n:>5} cases: {ok:>5} exit 0, {refused:>5} exit 2, {:>5} exit 1; {closed:>5} \
             with standard output closed",
            family.name,
            n - ok - refused
        );
    }
    assert!(per_family.iter().all(|&[n, ..]| n > 0));
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The exit status after the signal `name` (`INT`, `TERM`, `HUP`).
fn expected_status(name: &str) -> i32 {
    match name {
        "INT" => 130,
        "TERM" => 143,
        _ => 129,
    }
}

/// Signals at seeded moments to the commands that handle them: every one ends with 0 or 128 +
/// the signal, one line on standard error, no temporary file and no torn record.
#[test]
fn a_campaign_of_signals_keeps_the_promise() {
    let cases = std::env::var("EVIGRID_CAMPAIGN_CASES")
        .ok()
        .and_then(|v| v.parse::<usize>().ok())
        .unwrap_or(160)
        / 20;
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    corner_drive(d);
    let commands: [&[&str]; 3] = [
        &[
            "run", "--scans", "s", "--poses", "p.tum", "--out", "o", "--force",
        ],
        &["odometry", "s", "--out", "p.txt", "--force"],
        &["demo", "--frames", "3", "--out", "demo", "--force"],
    ];
    let mut rng = Rng::new(31);
    let mut failures = Vec::new();
    let mut signalled_cases = 0;
    for case in 0..cases.max(4) {
        let args = commands[case % commands.len()];
        let signal = ["INT", "TERM", "HUP"][rng.below(3)];
        let first_ms = rng.below(1500) as u64;
        let mut signals = vec![(signal, first_ms)];
        if rng.below(2) == 0 {
            signals.push((signal, rng.below(100) as u64));
        }
        let out = signalled(d, args, &signals);
        let code = out.status.code();
        // Before a command installs its handlers (the process starting, inputs still being
        // read, nothing written), a signal has its default action: the process ends by it, as
        // a shell reports 128 + n.
        let by_default = std::os::unix::process::ExitStatusExt::signal(&out.status)
            .is_some_and(|n| 128 + n == expected_status(signal));
        let stderr = String::from_utf8_lossy(&out.stderr);
        let expected = expected_status(signal);
        let problem = if code == Some(expected) {
            signalled_cases += 1;
            (stderr.lines().count() != 1).then(|| format!("not one line: {stderr:?}"))
        } else if code == Some(0) || by_default {
            None
        } else {
            Some(format!("exit {code:?}: {stderr:?}"))
        };
        let problem = problem.or_else(|| {
            let left = temporaries(d);
            for file in &left {
                let _ = fs::remove_file(file);
            }
            (!left.is_empty()).then(|| format!("temporaries left: {left:?}"))
        });
        records_are_whole(&d.join("o/frames.jsonl"));
        if let Some(problem) = problem {
            failures.push(format!(
                "case {case} {args:?} SIG{signal} {signals:?}: {problem}"
            ));
        }
    }
    println!(
        "{signalled_cases} of {} cases ended by their signal",
        cases.max(4)
    );
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Five KITTI scans (links to the shared data) and a bad one in the middle, in `dir/scans`.
fn scans_with_a_bad_one(dir: &Path) -> Option<()> {
    let source = geodata::testdata::shared_file("data/lidar/kitti-city-22")?;
    let mut names: Vec<_> = fs::read_dir(&source)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .collect();
    names.sort();
    fs::create_dir_all(dir.join("scans")).unwrap();
    for path in names.iter().take(5) {
        std::os::unix::fs::symlink(path, dir.join("scans").join(path.file_name()?)).unwrap();
    }
    let bad = pcd("WIDTH 1\nHEIGHT 1\nPOINTS 4000000000", "ascii\n1 2 3\n");
    fs::write(dir.join("scans/0000000002b.pcd"), bad).unwrap();
    Some(())
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_str(&fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap()
}

#[test]
fn a_bad_scan_is_skipped_and_named_or_with_strict_ends_the_run_with_a_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    if scans_with_a_bad_one(d).is_none() {
        eprintln!("skipped: shared KITTI scans not found (set EVIGRID_SHARED)");
        return;
    }
    let run = |out: &str, strict: bool| {
        let mut command = Command::new(env!("CARGO_BIN_EXE_evigrid"));
        command
            .args(["run", "--scans", "scans", "--out", out])
            .current_dir(d);
        if strict {
            command.arg("--strict");
        }
        command.output().unwrap()
    };
    let lenient = run("lenient", false);
    assert!(lenient.status.success(), "{lenient:?}");
    let s = summary(&d.join("lenient"));
    assert_eq!(s["complete"], true);
    assert_eq!(s["frames"], 5);
    assert_eq!(s["skipped_scans"][0]["scan"], "0000000002b.pcd");
    assert!(String::from_utf8_lossy(&lenient.stderr).contains("1 scan(s) skipped"));

    let strict = run("strict", true);
    assert_eq!(strict.status.code(), Some(2), "{strict:?}");
    let s = summary(&d.join("strict"));
    assert_eq!(s["complete"], false);
    assert!(
        s["stopped"].as_str().unwrap().contains("0000000002b.pcd"),
        "{s}"
    );
    let stderr = String::from_utf8_lossy(&strict.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("marked incomplete"), "{stderr}");
}

#[test]
fn an_interrupted_run_leaves_a_summary_marked_incomplete_and_no_temporary_file() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    if scans_with_a_bad_one(d).is_none() {
        eprintln!("skipped: shared KITTI scans not found (set EVIGRID_SHARED)");
        return;
    }
    let child = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(["run", "--scans", "scans", "--out", "out"])
        .current_dir(d)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Early, in the odometry's first pass or the first frames: either way the summary follows.
    std::thread::sleep(Duration::from_millis(150));
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let output = child.wait_with_output().unwrap();
    let s = summary(&d.join("out"));
    if output.status.code() == Some(0) {
        // The run finished before the signal arrived: nothing to check.
        assert_eq!(s["complete"], true);
        return;
    }
    assert_eq!(output.status.code(), Some(130), "{output:?}");
    assert_eq!(s["complete"], false);
    assert!(
        s["stopped"].as_str().unwrap().contains("interrupted"),
        "{s}"
    );
    let leftovers: Vec<_> = fs::read_dir(d.join("out"))
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

// ---------------------------------------------------------------------------------------------
// Issue 31: never lose a user's file, whatever the signal, the pipe or the disk.

/// A scan of a corner (two walls and a floor) from `back_m` metres behind the origin: 216
/// points, enough for the odometry to start its map and register the next scans.
fn corner_pcd(back_m: f64) -> String {
    let mut points = String::new();
    let mut n = 0;
    for i in 0..12 {
        for j in 0..6 {
            let (a, b) = (f64::from(i) * 0.5, f64::from(j) * 0.5);
            for [x, y, z] in [
                [8.0 + back_m, a - 3.0, b - 1.5],
                [a + 2.0 + back_m, 6.0, b - 1.5],
                [a + 2.0 + back_m, b - 1.0, -1.7],
            ] {
                points.push_str(&format!("{x} {y} {z}\n"));
                n += 1;
            }
        }
    }
    pcd(
        &format!("WIDTH {n}\nHEIGHT 1\nPOINTS {n}"),
        &format!("ascii\n{points}"),
    )
}

/// `dir/s`: three corner scans, 0.1 s apart (`dir/times.txt`), and their poses (`dir/p.tum`).
fn corner_drive(dir: &Path) {
    fs::create_dir_all(dir.join("s")).unwrap();
    for (k, name) in ["a", "b", "c"].iter().enumerate() {
        let scan = corner_pcd(0.3 * k as f64);
        fs::write(dir.join(format!("s/{name}.pcd")), scan).unwrap();
    }
    fs::write(dir.join("times.txt"), "0\n0.1\n0.2\n").unwrap();
    fs::write(
        dir.join("p.tum"),
        "0 0 0 0 0 0 0 1\n0.1 0.3 0 0 0 0 0 1\n0.2 0.6 0 0 0 0 0 1\n",
    )
    .unwrap();
}

/// Runs `evigrid args…` in `dir` with standard output going to `stdout`.
fn run_to(dir: &Path, args: &[&str], stdout: Stdio) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(stdout)
        .stderr(Stdio::piped())
        .output()
        .unwrap()
}

/// Runs `evigrid args…` in `dir` with standard output a pipe whose reader has already left.
fn run_closed_stdout(dir: &Path, args: &[&str]) -> std::process::Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    child.wait_with_output().unwrap()
}

#[test]
fn odometry_never_replaces_an_input_or_a_user_file() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    corner_drive(d);
    fs::write(d.join("calib.txt"), "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n").unwrap();
    std::os::unix::fs::symlink(d.join("s/a.pcd"), d.join("link.pcd")).unwrap();
    fs::hard_link(d.join("s/b.pcd"), d.join("hard.pcd")).unwrap();
    fs::write(d.join("notes.txt"), "mine").unwrap();
    let before: Vec<(String, Vec<u8>)> =
        ["s/a.pcd", "s/b.pcd", "times.txt", "calib.txt", "notes.txt"]
            .iter()
            .map(|f| (f.to_string(), fs::read(d.join(f)).unwrap()))
            .collect();
    fn odometry<'a>(out: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
        let mut args = vec![
            "odometry",
            "s",
            "--times",
            "times.txt",
            "--calib",
            "calib.txt",
            "--out",
            out,
        ];
        args.extend_from_slice(extra);
        args
    }
    // Issue 31 #1: each of these was overwritten, exit 0. With --force too: never an input.
    for out in ["s/a.pcd", "link.pcd", "hard.pcd", "times.txt", "calib.txt"] {
        assert_bad_input(d, &odometry(out, &["--force"]), "is the input");
    }
    assert_bad_input(
        d,
        &odometry("notes.txt", &[]),
        "exists; evigrid replaces a file only with --force",
    );
    // The side file: an existing user's file, and the command's own --times input.
    fs::write(d.join("k.times.txt"), "0\n0.1\n0.2\n").unwrap();
    assert_bad_input(
        d,
        &odometry("k.txt", &["--format", "kitti"]),
        "k.times.txt: exists",
    );
    let own_times = [
        "odometry",
        "s",
        "--times",
        "k.times.txt",
        "--out",
        "k.txt",
        "--format",
        "kitti",
        "--force",
    ];
    assert_bad_input(d, &own_times, "k.times.txt: is the input");
    assert_bad_input(
        d,
        &odometry("/dev/null", &["--force"]),
        "not a regular file",
    );
    // Issue 31 #7: an unwritable place is bad input, as for `run`.
    assert_bad_input(d, &odometry("/proc/poses.txt", &[]), "cannot write here");
    for (file, bytes) in &before {
        assert_eq!(
            &fs::read(d.join(file)).unwrap(),
            bytes,
            "{file} was changed"
        );
    }
    // A new file is written, and replaced with --force.
    for extra in [&[][..], &["--force"][..]] {
        let done = run_limited(d, &odometry("poses.txt", extra));
        assert_eq!(done.code, Some(0), "{done:?}");
    }
    assert_eq!(
        fs::read_to_string(d.join("poses.txt"))
            .unwrap()
            .lines()
            .count(),
        4
    );

    // A KITTI raw drive: its scans, times, OXTS packets and the calibration above it.
    let Some(drive) = geodata::testdata::shared_file(
        "data/lidar/kitti-raw-0013/2011_09_26/2011_09_26_drive_0013_sync",
    ) else {
        eprintln!("skipped the KITTI raw half: shared drive not found (set EVIGRID_SHARED)");
        return;
    };
    let date = d.join("2011_09_26");
    fs::create_dir_all(&date).unwrap();
    let calib = drive.parent().unwrap().join("calib_imu_to_velo.txt");
    fs::copy(&calib, date.join("calib_imu_to_velo.txt")).unwrap();
    std::os::unix::fs::symlink(&drive, date.join("drive")).unwrap();
    for out in [
        "2011_09_26/drive/velodyne_points/data/0000000001.bin",
        "2011_09_26/drive/velodyne_points/timestamps.txt",
        "2011_09_26/drive/oxts/data/0000000003.txt",
        "2011_09_26/calib_imu_to_velo.txt",
    ] {
        assert_bad_input(
            d,
            &["odometry", "2011_09_26/drive", "--out", out, "--force"],
            "is the input",
        );
    }
}

#[test]
fn a_closed_pipe_ends_quietly_and_a_full_standard_output_in_one_line() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    corner_drive(d);
    // Issue 31 #2: `evigrid run … | head -c 10` panicked, exit 101, no summary.
    let run = [
        "run",
        "--scans",
        "s",
        "--poses",
        "p.tum",
        "--out",
        "o",
        "--no-mcap",
    ];
    let closed = run_closed_stdout(d, &run);
    assert_eq!(closed.status.code(), Some(0), "{closed:?}");
    assert!(closed.stderr.is_empty(), "{closed:?}");
    assert_eq!(summary(&d.join("o"))["complete"], true);
    let closed = run_closed_stdout(d, &["odometry", "s", "--out", "q.txt"]);
    assert_eq!(closed.status.code(), Some(0), "{closed:?}");
    assert_eq!(
        fs::read_to_string(d.join("q.txt")).unwrap().lines().count(),
        4
    );
    let closed = run_closed_stdout(d, &["config", "--print"]);
    assert_eq!(closed.status.code(), Some(0), "{closed:?}");
    assert!(closed.stderr.is_empty(), "{closed:?}");

    // `>/dev/full`: the outputs on disk are finished, then one line and exit 1.
    let Ok(full) = fs::File::create("/dev/full") else {
        eprintln!("skipped the /dev/full half: no /dev/full");
        return;
    };
    let out = run_to(d, &["odometry", "s", "--out", "r.txt"], Stdio::from(full));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{out:?}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("evigrid: standard output: No space left on device"),
        "{stderr}"
    );
    assert!(d.join("r.txt").is_file());
    for args in [&["config", "--print"][..], &["--help"][..]] {
        let out = run_to(d, args, Stdio::from(fs::File::create("/dev/full").unwrap()));
        assert_eq!(out.status.code(), Some(1), "{args:?}: {out:?}");
        assert_eq!(String::from_utf8_lossy(&out.stderr).lines().count(), 1);
    }
}

/// Spawns `evigrid args…` in `dir`, sends the signals `(name, delay before it)`, and waits.
fn signalled(dir: &Path, args: &[&str], signals: &[(&str, u64)]) -> std::process::Output {
    let child = Command::new(env!("CARGO_BIN_EXE_evigrid"))
        .args(args)
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    for (signal, delay_ms) in signals {
        std::thread::sleep(Duration::from_millis(*delay_ms));
        let _ = Command::new("kill")
            .args([format!("-{signal}"), child.id().to_string()])
            .status();
    }
    child.wait_with_output().unwrap()
}

/// Files under `dir` whose names hold `.tmp-` (a temporary left behind).
fn temporaries(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut found = Vec::new();
    for entry in fs::read_dir(dir).into_iter().flatten().flatten() {
        let path = entry.path();
        if path.is_dir() {
            found.extend(temporaries(&path));
        } else if entry.file_name().to_string_lossy().contains(".tmp-") {
            found.push(path);
        }
    }
    found
}

/// The 22 KITTI city scans (links to the shared data) in `dir/city`, and `dir/still.tum`: a pose
/// for each, standing still, so that a run starts its frames at once.
fn city_drive(dir: &Path) -> Option<()> {
    let source = geodata::testdata::shared_file("data/lidar/kitti-city-22")?;
    fs::create_dir_all(dir.join("city")).unwrap();
    let mut poses = String::new();
    let mut names: Vec<_> = fs::read_dir(&source)
        .ok()?
        .flatten()
        .map(|e| e.path())
        .collect();
    names.sort();
    for (k, path) in names.iter().enumerate() {
        std::os::unix::fs::symlink(path, dir.join("city").join(path.file_name()?)).unwrap();
        poses.push_str(&format!("{} 0 0 0 0 0 0 1\n", 0.1 * k as f64));
    }
    fs::write(dir.join("still.tum"), poses).unwrap();
    Some(())
}

/// Every line of a `frames.jsonl` is a whole JSON record.
fn records_are_whole(path: &Path) {
    let Ok(text) = fs::read_to_string(path) else {
        return;
    };
    assert!(
        text.is_empty() || text.ends_with('\n'),
        "a torn last line: {text:?}"
    );
    for line in text.lines() {
        assert!(
            serde_json::from_str::<serde_json::Value>(line).is_ok(),
            "a torn record: {line:?}"
        );
    }
}

#[test]
fn every_signal_ends_a_run_cleanly_and_a_second_one_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    if city_drive(d).is_none() {
        eprintln!("skipped: shared KITTI scans not found (set EVIGRID_SHARED)");
        return;
    }
    // Issue 31 #3: a SIGHUP killed the run (no summary, a temporary left).
    let run = |out: &'static str| {
        [
            "run",
            "--scans",
            "city",
            "--poses",
            "still.tum",
            "--out",
            out,
        ]
    };
    let hup = signalled(d, &run("hup"), &[("HUP", 300)]);
    if hup.status.code() == Some(0) {
        eprintln!("not checked: the run ended before the SIGHUP");
    } else {
        assert_eq!(hup.status.code(), Some(129), "{hup:?}");
        assert_eq!(summary(&d.join("hup"))["complete"], false);
        // The stop text names the signal that arrived (it said "SIGINT or SIGTERM").
        assert_eq!(summary(&d.join("hup"))["stopped"], "interrupted by SIGHUP");
        assert!(temporaries(&d.join("hup")).is_empty());
    }
    // A second signal 50 ms after the first: at once, but no temporary and no torn record.
    for (signal, code) in [("INT", 130), ("TERM", 143)] {
        let out = format!("twice-{signal}");
        let args = [
            "run",
            "--scans",
            "city",
            "--poses",
            "still.tum",
            "--out",
            &out,
        ];
        let twice = signalled(d, &args, &[(signal, 2500), (signal, 50)]);
        if twice.status.code() == Some(0) {
            eprintln!("not checked: the run ended before the SIG{signal}s");
            continue;
        }
        assert_eq!(twice.status.code(), Some(code), "{twice:?}");
        let stderr = String::from_utf8_lossy(&twice.stderr);
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            temporaries(&d.join(&out)).is_empty(),
            "{:?}",
            temporaries(&d.join(&out))
        );
        records_are_whole(&d.join(&out).join("frames.jsonl"));
    }
}

#[test]
fn an_interrupted_odometry_writes_the_poses_so_far_marked_incomplete() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    if city_drive(d).is_none() {
        eprintln!("skipped: shared KITTI scans not found (set EVIGRID_SHARED)");
        return;
    }
    let out = signalled(d, &["odometry", "city", "--out", "p.txt"], &[("INT", 1500)]);
    if out.status.code() == Some(0) {
        eprintln!("not checked: the odometry ended before the signal");
        return;
    }
    assert_eq!(out.status.code(), Some(130), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    if let Ok(poses) = fs::read_to_string(d.join("p.txt")) {
        assert!(
            poses.starts_with("# incomplete: interrupted by SIGINT after "),
            "{poses}"
        );
        assert!(stderr.contains("written to p.txt (incomplete)"), "{stderr}");
    }
    assert!(temporaries(d).is_empty());
}

/// An output folder a first signal stopped: the outputs of the work done, marked incomplete in
/// the marker (with the signal), no temporary; `stderr` one line saying so.
fn assert_stopped_and_finished(folder: &Path, signal: &str, stderr: &[u8]) {
    let stderr = String::from_utf8_lossy(stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("(marked incomplete)"), "{stderr}");
    assert!(temporaries(folder).is_empty(), "{:?}", temporaries(folder));
    let marker = fs::read_to_string(folder.join(".evigrid-output")).unwrap();
    assert!(marker.contains("incomplete: true"), "{marker}");
    assert!(
        marker.contains(&format!("interrupted: SIG{signal}")),
        "{marker}"
    );
    assert!(marker.contains("file: report.md"), "{marker}");
}

#[test]
fn a_first_signal_stops_a_demo_between_frames_and_finishes_its_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    // Issue 31 #3: `demo` had no handling: killed, a temporary left, nothing marked. Then the
    // first signal ended it at once; now it stops between frames and finishes what it has.
    let out = signalled(
        d,
        &["demo", "--frames", "40", "--out", "demo"],
        &[("TERM", 3000)],
    );
    if out.status.code() == Some(0) {
        eprintln!("not checked: the demo ended before the signal");
        return;
    }
    assert_eq!(out.status.code(), Some(143), "{out:?}");
    let folder = d.join("demo");
    assert_stopped_and_finished(&folder, "TERM", &out.stderr);
    if folder.join("metrics.json").is_file() {
        let metrics: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(folder.join("metrics.json")).unwrap())
                .unwrap();
        assert_eq!(metrics["complete"], false);
        let run = metrics["frames_run"].as_u64().unwrap();
        assert!((1..40).contains(&run), "{run}");
        assert!(folder.join("decision.gif").is_file());
        assert!(folder.join("index.html").is_file());
    }
}

#[test]
fn a_second_signal_ends_a_demo_at_once_without_a_temporary() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let out = signalled(
        d,
        &["demo", "--frames", "40", "--out", "demo"],
        &[("INT", 3000), ("INT", 30)],
    );
    if out.status.code() == Some(0) {
        eprintln!("not checked: the demo ended before the signals");
        return;
    }
    assert_eq!(out.status.code(), Some(130), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(temporaries(&d.join("demo")).is_empty());
    let marker = fs::read_to_string(d.join("demo/.evigrid-output")).unwrap();
    assert!(marker.contains("interrupted: SIGINT"), "{marker}");
}

/// A long scenario on the shared village map, in `dir`: (map, scenario).
fn long_scenario(dir: &Path) -> Option<(String, String)> {
    let map = geodata::testdata::shared_file("data/osm/bavarian-village.osm")?;
    let scenario = dir.join("long.toml");
    fs::write(
        &scenario,
        "seed = 4\nduration_s = 20.0\n[traffic]\nmoving_cars = 2\nparked_cars = 2\n",
    )
    .unwrap();
    Some((map.display().to_string(), scenario.display().to_string()))
}

#[test]
fn a_first_signal_stops_eval_between_frames_and_writes_the_report_of_those_run() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let Some((map, scenario)) = long_scenario(d) else {
        eprintln!("skipped: shared map not found (set EVIGRID_SHARED)");
        return;
    };
    let args = [
        "eval",
        "--map",
        &map,
        "--scenario",
        &scenario,
        "--seeds",
        "3",
        "--out",
        "eval",
    ];
    let out = signalled(d, &args, &[("INT", 4000)]);
    if out.status.code() == Some(0) {
        eprintln!("not checked: the evaluation ended before the signal");
        return;
    }
    assert_eq!(out.status.code(), Some(130), "{out:?}");
    let folder = d.join("eval");
    assert_stopped_and_finished(&folder, "INT", &out.stderr);
    let metrics: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(folder.join("metrics.json")).unwrap()).unwrap();
    assert_eq!(metrics["complete"], false);
    assert!(metrics["frames_run"].as_u64().unwrap() < 3 * 200);
    let report = fs::read_to_string(folder.join("report.md")).unwrap();
    assert!(report.contains("**Incomplete**"), "{report}");
}

#[test]
fn a_first_signal_stops_tune_between_candidates_and_writes_the_best_so_far() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let Some((map, scenario)) = long_scenario(d) else {
        eprintln!("skipped: shared map not found (set EVIGRID_SHARED)");
        return;
    };
    let args = [
        "tune",
        "--map",
        &map,
        "--scenario",
        &scenario,
        "--seeds",
        "1",
        "--rounds",
        "3",
        "--out",
        "tune",
    ];
    let out = signalled(d, &args, &[("HUP", 4000)]);
    if out.status.code() == Some(0) {
        eprintln!("not checked: the search ended before the signal");
        return;
    }
    assert_eq!(out.status.code(), Some(129), "{out:?}");
    let folder = d.join("tune");
    assert_stopped_and_finished(&folder, "HUP", &out.stderr);
    assert!(folder.join("tuned.toml").is_file());
    let json: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(folder.join("tune.json")).unwrap()).unwrap();
    assert_eq!(json["search"]["complete"], false);
    assert!(!json["search"]["candidates"].as_array().unwrap().is_empty());
}

#[test]
fn a_first_signal_stops_bench_between_rounds() {
    let tmp = tempfile::tempdir().unwrap();
    let args = [
        "bench",
        "--synthetic-only",
        "--sizes",
        "1000",
        "--rounds",
        "10000",
        "--naive-rounds",
        "0",
    ];
    let out = signalled(tmp.path(), &args, &[("TERM", 3000)]);
    if out.status.code() == Some(0) {
        eprintln!("not checked: the bench ended before the signal");
        return;
    }
    assert_eq!(out.status.code(), Some(143), "{out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains("bench stopped"), "{stderr}");
}

#[test]
fn the_other_reproducers_of_issue_31_are_bad_input() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    corner_drive(d);
    // #4: a FIFO as a bag hung.
    let fifo = d.join("f.mcap");
    if Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .is_ok_and(|s| s.success())
    {
        assert_bad_input(d, &["bag", "info", "f.mcap"], "not a regular file");
    }
    // #5: negative times started the run, then stopped at frame 0 with exit 1.
    fs::write(d.join("neg.txt"), "-0.2\n-0.1\n0\n").unwrap();
    assert_bad_input(
        d,
        &[
            "run", "--scans", "s", "--times", "neg.txt", "--poses", "p.tum", "--out", "neg",
        ],
        "neg.txt:1: time -0.2 s is negative",
    );
    assert!(!d.join("neg").exists());
    // #8: `nan` in four `[sensor.ground]` keys was accepted.
    for key in [
        "min_range_m",
        "max_range_m",
        "min_obstacle_height_m",
        "max_obstacle_height_m",
    ] {
        fs::write(
            d.join("nan.toml"),
            format!("[sensor.ground]\n{key} = nan\n"),
        )
        .unwrap();
        assert_bad_input(
            d,
            &["config", "--check", "nan.toml"],
            &format!("sensor.ground.{key} = nan"),
        );
    }
    // #9: absurd values.
    fs::write(d.join("cell.toml"), "[grid]\ncell_size_m = 1e-300\n").unwrap();
    assert_bad_input(
        d,
        &["config", "--check", "cell.toml"],
        "grid.cell_size_m = 1e-300 is below 0.01",
    );
    fs::write(
        d.join("far.tum"),
        "0 0 0 0 0 0 0 1\n0.1 0 0 1e308 0 0 0 1\n0.2 0 0 0 0 0 0 1\n",
    )
    .unwrap();
    assert_bad_input(
        d,
        &["run", "--scans", "s", "--poses", "far.tum", "--out", "far"],
        "far.tum:2: position coordinate 1e308 m",
    );
    assert_bad_input(
        d,
        &[
            "run",
            "--scans",
            "s",
            "--poses",
            "p.tum",
            "--mounting",
            "0,0,1e6,0,0,0",
            "--out",
            "m",
        ],
        "beyond 50 m",
    );
    for (name, scan) in [
        ("empty", pcd("WIDTH 0\nHEIGHT 1\nPOINTS 0", "ascii\n")),
        (
            "nan",
            pcd(
                "WIDTH 2\nHEIGHT 1\nPOINTS 2",
                "ascii\nnan nan nan\nnan 1 2\n",
            ),
        ),
        ("one", pcd("WIDTH 1\nHEIGHT 1\nPOINTS 1", "ascii\n10 0 0\n")),
    ] {
        let folder = scans(d, &format!("deg-{name}"), scan.as_bytes());
        assert_bad_input(
            d,
            &["odometry", &folder, "--out", &format!("{name}.txt")],
            "usable points",
        );
        assert!(!d.join(format!("{name}.txt")).exists());
    }
    // #10: the deprecated variant name added a warning line before the one-line error.
    fs::write(d.join("bad-scenario.toml"), "duration_s = 1e9\n").unwrap();
    assert_bad_input(
        d,
        &[
            "eval",
            "--map",
            "m.geojson",
            "--scenario",
            "bad-scenario.toml",
            "--out",
            "e",
            "--variants",
            "full",
        ],
        "evigrid: ",
    );
}

/// A 64 KiB tmpfs at `dir/full`, nearly filled; `None` (with a note) where it cannot be mounted
/// (not root, no tmpfs). Unmounted when dropped.
struct FullDisk(std::path::PathBuf);

impl FullDisk {
    fn mount(dir: &Path) -> Option<Self> {
        let at = dir.join("full");
        fs::create_dir_all(&at).ok()?;
        let mounted = Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"])
            .arg(&at)
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        if !mounted {
            eprintln!("skipped: cannot mount a small tmpfs (the full-disk tests need root)");
            return None;
        }
        Some(Self(at))
    }

    /// Fills all but `free` bytes.
    fn fill(&self, free: usize) {
        let filler = self.0.join("filler");
        let _ = fs::write(&filler, vec![0u8; 64 * 1024]);
        let len = fs::metadata(&filler).map_or(0, |m| m.len() as usize);
        let _ = fs::write(&filler, vec![0u8; len.saturating_sub(free)]);
    }
}

impl Drop for FullDisk {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

/// Exit 1 with one line naming a file under `full/`.
fn assert_environment_failure(outcome: &Outcome, args: &[&str]) {
    assert_eq!(outcome.code, Some(1), "{args:?}: {outcome:?}");
    let lines: Vec<&str> = outcome.stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: {:?}", outcome.stderr);
    assert!(
        lines[0].starts_with("evigrid: ") && lines[0].contains("full/"),
        "{lines:?}"
    );
}

#[test]
fn a_full_disk_is_one_line_and_exit_1_and_leaves_no_temporary() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    corner_drive(d);
    let Some(disk) = FullDisk::mount(d) else {
        return;
    };
    // Issue 31 #7: `run`, `demo` and `odometry` on a full disk. tmpfs gives whole pages: with
    // two free, the folder's marker fits and the outputs do not; with none, an empty probe file
    // still does (the place is writable) and the pose file does not.
    let runs: [(&[&str], usize); 3] = [
        (
            &[
                "run", "--scans", "s", "--poses", "p.tum", "--out", "full/run",
            ],
            8192,
        ),
        (&["demo", "--frames", "2", "--out", "full/demo"], 8192),
        (
            &[
                "odometry",
                "s",
                "--out",
                "full/poses.txt",
                "--format",
                "kitti",
            ],
            0,
        ),
    ];
    for (args, free) in runs {
        disk.fill(free);
        let outcome = run_limited(d, args);
        assert_environment_failure(&outcome, args);
        assert!(temporaries(&d.join("full")).is_empty(), "{args:?}");
    }
    let marker = fs::read_to_string(d.join("full/demo/.evigrid-output")).unwrap_or_default();
    assert!(
        marker.is_empty() || marker.contains("incomplete: true"),
        "{marker}"
    );
}
