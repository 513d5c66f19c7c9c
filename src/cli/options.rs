//! `bvhc options [--preset NAME] [flags]`: the options a conversion with these flags would use, resolved and
//! checked, as the JSON of the metadata's `build` object (the file records exactly this); exit 2, naming the
//! settings, where a flag would do nothing. `bvhc options --list [--json | --markdown]`: the options table.

use bvhc::convert::metadata::BuildRecord;

use super::args::OptionsArgs;
use super::output::{outln, print};
use super::{Exit, fail};

/// Prints the resolved options.
pub fn options(args: &OptionsArgs) -> Exit {
    if args.list {
        let listing = if args.json {
            format!("{:#}\n", bvhc::options::listing::to_json())
        } else if args.markdown {
            bvhc::options::listing::markdown()
        } else {
            bvhc::options::listing::text()
        };
        return print(&listing, Exit::Success);
    }
    let settings = match args.options.settings() {
        Ok(settings) => settings,
        Err(message) => return fail(Exit::InvalidInput, message),
    };
    match settings.resolve() {
        Ok(options) => {
            let mut out = String::new();
            outln!(out, "{:#}", BuildRecord::of(&options).to_value());
            print(&out, Exit::Success)
        }
        Err(error) => fail(Exit::Usage, error),
    }
}
