//! The `relight view` command line (feature `cli`): the binary only parses these and calls
//! [`run_cli`].

use crate::{run, ViewArgs, ViewError};
use std::path::PathBuf;

/// Arguments of `relight view`.
#[derive(clap::Args, Debug)]
#[command(after_help = concat!(
    "Keyboard and mouse (also in the window's help panel, H):\n",
    crate::shortcuts!(),
    "\n\nScript actions (--script FILE, one per line, # comments):\n",
    crate::script::script_syntax!(),
    "\n\nExit status: 0, or 1 with the reason on stderr: no Vulkan driver (what to install is \
     named), no display, a script line that does not parse (file:line), or, in a scripted \
     run only, an error shown in the window (each is also printed on stdout)."
))]
pub struct Args {
    /// The baked bundle (any method; the GPU renders sh, hybrid, sg and cuts), or a model
    /// file (.glb, .gltf, .obj, .ply) or scene description (.json), baked first as `relight
    /// bake` does (method from the materials, --env the light) into a cache that the next view
    /// of the same file reuses.
    pub bundle: PathBuf,
    /// Start with this environment map (.hdr / .exr) instead of the bundle's.
    #[arg(long)]
    pub env: Option<PathBuf>,
    /// Drive the viewer with a file of actions (see below), e.g. for tests under Xvfb.
    #[arg(long)]
    pub script: Option<PathBuf>,
    /// Window size, WIDTHxHEIGHT logical pixels, each in 64..=8192.
    #[arg(long, default_value = "1280x800", value_parser = parse_size)]
    pub size: (u32, u32),
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let bad = || format!("'{s}' is not WIDTHxHEIGHT (e.g. 1280x800)");
    let (w, h) = s.split_once('x').ok_or_else(bad)?;
    Ok((w.parse().map_err(|_| bad())?, h.parse().map_err(|_| bad())?))
}

/// Run `relight view` with parsed arguments.
///
/// # Errors
/// As [`run`].
pub fn run_cli(a: Args) -> Result<(), ViewError> {
    run(&ViewArgs {
        bundle: a.bundle,
        env: a.env,
        script: a.script,
        size: a.size,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn sizes_parse_or_say_what_is_expected() {
        assert_eq!(super::parse_size("640x400"), Ok((640, 400)));
        assert!(super::parse_size("640")
            .unwrap_err()
            .contains("WIDTHxHEIGHT"));
        assert!(super::parse_size("ax3").is_err());
    }
}
