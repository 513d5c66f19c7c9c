//! `bvhc options [--preset NAME] [flags]`: the options a conversion with these flags would use, resolved and
//! checked, as the JSON of the metadata's `build` object (the file records exactly this); exit 2, naming the
//! settings, where a flag would do nothing.

use bvhc::convert::metadata::BuildRecord;
use bvhc::options::resolve;

use super::args::OptionsArgs;
use super::output::{outln, print};
use super::{Exit, fail};

/// Prints the resolved options.
pub fn options(args: &OptionsArgs) -> Exit {
    let overrides = match args.options.overrides() {
        Ok(overrides) => overrides,
        Err(message) => return fail(Exit::InvalidInput, message),
    };
    match resolve(args.options.preset, &overrides) {
        Ok(options) => {
            let mut out = String::new();
            outln!(out, "{:#}", BuildRecord::of(&options).to_value());
            print(&out, Exit::Success)
        }
        Err(error) => fail(Exit::Usage, error),
    }
}
