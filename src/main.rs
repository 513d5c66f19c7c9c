//! The `bvhc` command line (first version: convert and verify; issue #5 brings the full interface).
#![forbid(unsafe_code)]

use std::path::PathBuf;
use std::process::ExitCode;

use bvhc::loader::BvhFile;

const USAGE: &str = "usage:
  bvhc INPUT -o OUTPUT.bvh   convert a scene (.ply, .obj, optionally .gz) into a .bvh file
  bvhc verify FILE.bvh       check every validity rule of a .bvh file

exit codes: 0 success, 1 invalid input or failed conversion, 2 usage error";

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    match args.iter().map(String::as_str).collect::<Vec<_>>().as_slice() {
        ["verify", file] => verify(PathBuf::from(file)),
        [input, "-o", output] | ["-o", output, input] => convert(PathBuf::from(input), PathBuf::from(output)),
        ["-h"] | ["--help"] => {
            println!("{USAGE}");
            ExitCode::SUCCESS
        }
        _ => {
            eprintln!("{USAGE}");
            ExitCode::from(2)
        }
    }
}

fn convert(input: PathBuf, output: PathBuf) -> ExitCode {
    match bvhc::convert::convert(&input, &output) {
        Ok(report) => {
            println!(
                "{}: {} triangles, {} nodes, {} bytes",
                report.output.display(),
                report.triangle_count,
                report.node_count,
                report.file_byte_len
            );
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("bvhc: {error}");
            ExitCode::from(1)
        }
    }
}

fn verify(path: PathBuf) -> ExitCode {
    let result = BvhFile::read(&path).and_then(|file| file.view().verify().map(|()| file).map_err(Into::into));
    match result {
        Ok(file) => {
            let view = file.view();
            let (major, minor) = view.version();
            println!(
                "{}: valid .bvh {major}.{minor}, {} nodes, {} triangles",
                path.display(),
                view.nodes().len(),
                view.triangles().len()
            );
            ExitCode::SUCCESS
        }
        Err(error) => {
            eprintln!("bvhc: {}: {error}", path.display());
            ExitCode::from(1)
        }
    }
}
