//! Byte-identical outputs: every file the binary writes for the command lines of
//! `cli/tests/data/golden_outputs.txt` must hash to what was recorded there (see that file for
//! what is covered and when it was recorded). A behaviour-preserving change (a
//! reorganisation, a refactoring) must leave every byte as it was.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// FNV-1a, 64 bits: a regression fingerprint of a file's bytes (not a security hash).
fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// Byte range of the seconds a form-factor cache file records (magic 13, version 4, key 16,
/// n 8, nnz 8): the time it took, which no two runs share.
const CACHE_SECONDS: std::ops::Range<usize> = 49..57;

fn fingerprint(name: &str, mut bytes: Vec<u8>) -> String {
    if name.ends_with(".ff") && bytes.len() >= CACHE_SECONDS.end {
        bytes[CACHE_SECONDS].fill(0);
    }
    format!("{:016x}:{}", fnv1a(&bytes), bytes.len())
}

/// Every file under `dir`, by its path relative to `dir` ('/'-separated).
fn files(dir: &Path, prefix: &str, out: &mut BTreeMap<String, PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let entry = entry.unwrap();
        let name = format!("{prefix}{}", entry.file_name().to_string_lossy());
        if entry.file_type().unwrap().is_dir() {
            files(&entry.path(), &format!("{name}/"), out);
        } else {
            out.insert(name, entry.path());
        }
    }
}

/// Splits a command line on spaces, with '…' quoting (no escapes): enough for the cases file.
fn words(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (k, part) in line.split('\'').enumerate() {
        if k % 2 == 1 {
            out.push(part.to_string());
        } else {
            out.extend(part.split_whitespace().map(str::to_string));
        }
    }
    out
}

/// Runs one case's commands in a fresh directory; its outputs as `name=fingerprint` words.
fn run_case(root: &Path, name: &str, commands: &str) -> Vec<String> {
    let out = crate::support::temp_dir(&format!("golden-{name}"));
    let mut outputs = Vec::new();
    for (k, command) in commands.split(" ; ").enumerate() {
        let args = words(&command.replace("{out}", &out.display().to_string()));
        // The estimate `info` prints at the reference machine's speed, not this one's.
        let o = Command::new(env!("CARGO_BIN_EXE_radiosity"))
            .env("RADIOSITY_SPEED", "1")
            .args(&args)
            .current_dir(root)
            .output()
            .expect("the binary runs");
        assert!(
            o.status.success(),
            "{name}: `{command}` failed: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        if !o.stdout.is_empty() {
            outputs.push(format!("stdout.{k}={}", fingerprint("", o.stdout)));
        }
    }
    let mut found = BTreeMap::new();
    files(&out, "", &mut found);
    for (file, path) in found {
        let text = fingerprint(&file, std::fs::read(&path).unwrap());
        outputs.push(format!("{file}={text}"));
    }
    outputs.sort();
    outputs
}

#[test]
fn golden_outputs_are_byte_identical() {
    let root = crate::support::root();
    let table = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data/golden_outputs.txt");
    let text = std::fs::read_to_string(&table).unwrap();
    let record = std::env::var_os("RADIOSITY_GOLDEN_RECORD").is_some();
    let mut recorded = String::new();
    let mut failures = Vec::new();
    for line in text.lines() {
        let fields: Vec<&str> = line.split(" | ").collect();
        if line.starts_with('#') || line.trim().is_empty() {
            recorded.push_str(line);
            recorded.push('\n');
            continue;
        }
        assert!(fields.len() >= 2, "malformed case line: {line}");
        let (name, commands) = (fields[0], fields[1]);
        let got = run_case(&root, name, commands);
        if record {
            recorded.push_str(&format!("{name} | {commands} | {}\n", got.join(" ")));
            continue;
        }
        let expected: Vec<String> = fields
            .get(2)
            .unwrap_or_else(|| panic!("{name}: no recorded outputs"))
            .split_whitespace()
            .map(str::to_string)
            .collect();
        assert!(!expected.is_empty(), "{name}: no recorded outputs");
        if got != expected {
            failures.push(format!(
                "{name}:\n  expected {}\n  got      {}",
                expected.join(" "),
                got.join(" ")
            ));
        }
    }
    if record {
        std::fs::write(&table, recorded).unwrap();
        return;
    }
    assert!(
        failures.is_empty(),
        "outputs differ from the recorded ones:\n{}",
        failures.join("\n")
    );
}
