//! `relight view --script FILE`: the viewer driven by a file of actions, one per line, as a
//! user would drive it (used by the tests under Xvfb and to make the README's screenshots).
//!
//! Blank lines and lines starting with `#` are skipped. Every other line is one action; the
//! actions run in order, each in its own UI frame, and the script waits where an action says
//! so (`wait-frames`, `wait-reference`, and every screenshot until its file is written).
//! A line that does not parse is an error naming the file and the line, before the window
//! opens.

use std::path::{Path, PathBuf};

/// One scripted action.
#[derive(Clone, Debug, PartialEq)]
pub enum Action {
    /// Let this many UI frames pass.
    WaitFrames(u32),
    /// Wait until the progressive reference of the current view has at least this many
    /// samples per pixel (at most [`WAIT_REFERENCE_SECONDS`] seconds).
    WaitReference(u32),
    /// Orbit the camera about its target: yaw and pitch, degrees.
    Orbit(f32, f32),
    /// Pan the camera: fractions of the view's width and height (right, up).
    Pan(f32, f32),
    /// Multiply the distance to the target (`< 1` moves closer).
    Zoom(f32),
    /// The framing of the whole scene from the bundle camera's direction.
    ResetCamera,
    /// The bundle's own camera.
    BundleCamera,
    /// Rotate the environment about +Y by this many degrees (added to the current rotation).
    RotateEnv(f32),
    /// Set the display exposure, EV (`2^EV` times the radiance).
    Exposure(f32),
    /// Use the procedural sky with the sun at this elevation and azimuth, degrees.
    Sky(f32, f32),
    /// Load an environment map from a file.
    Env(PathBuf),
    /// Use the bundle's own environment.
    BundleEnv,
    /// Switch to this method (`sh`, `hybrid`, `sg`, ...).
    Method(String),
    /// Draw the environment behind the objects (`on`/`off`).
    Background(bool),
    /// Show the progressive reference on the right of the split (`off`, `reference`,
    /// `heatmap`).
    Split(SplitMode),
    /// Where the split is, as a fraction of the view's width from the left.
    SplitAt(f32),
    /// Write the 3D view (`.png` as displayed, `.exr` linear radiance).
    Screenshot(PathBuf),
    /// Write the whole window, panels included (`.png` only).
    ScreenshotWindow(PathBuf),
    /// Print the viewer's state (method, camera, environment, reference, error) on stdout.
    PrintState,
    /// Close the window.
    Quit,
}

/// What the right of the split shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitMode {
    /// No split: the GPU frame everywhere.
    Off,
    /// The progressive path-traced reference.
    Reference,
    /// The heat map of the luminance error of the GPU frame against the reference.
    Heatmap,
}

impl SplitMode {
    /// The name in scripts and on screen.
    pub fn name(self) -> &'static str {
        match self {
            SplitMode::Off => "off",
            SplitMode::Reference => "reference",
            SplitMode::Heatmap => "heatmap",
        }
    }
}

/// Longest wait of `wait-reference`, seconds: past it the script fails (the reference thread
/// is stuck or far too slow for a test).
pub const WAIT_REFERENCE_SECONDS: u64 = 300;

/// A script line that does not parse.
#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}: {problem}")]
pub struct ScriptError {
    /// The script file.
    pub file: String,
    /// The line, from 1.
    pub line: usize,
    /// What is wrong.
    pub problem: String,
}

/// A parsed script: its actions with their line numbers.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Script {
    /// `(line, action)` in order.
    pub actions: Vec<(usize, Action)>,
}

/// Every action's syntax (a macro so that `--help` can `concat!` it).
macro_rules! script_syntax {
    () => {
        "wait-frames N | wait-reference SPP | orbit YAW PITCH | pan DX DY | \
zoom FACTOR | reset-camera | bundle-camera | rotate-env DEG | exposure EV | sky ELEV AZIMUTH | \
env FILE | bundle-env | method NAME | background on|off | split off|reference|heatmap | \
split-at FRACTION | screenshot FILE.png|FILE.exr | screenshot-window FILE.png | print-state | quit"
    };
}
#[cfg_attr(not(feature = "cli"), allow(unused_imports))]
pub(crate) use script_syntax;

/// Every action's syntax, for errors and `--help`.
pub const SYNTAX: &str = script_syntax!();

impl Script {
    /// Read and parse `path`.
    ///
    /// # Errors
    /// The file cannot be read, or a line does not parse (file and line named).
    pub fn read(path: &Path) -> Result<Script, ScriptError> {
        let text = std::fs::read_to_string(path).map_err(|e| ScriptError {
            file: path.display().to_string(),
            line: 0,
            problem: format!("cannot read the script: {e}"),
        })?;
        Script::parse(&text, &path.display().to_string())
    }

    /// Parse `text` (from `file`, named in errors). Relative paths stay relative to the
    /// current directory.
    ///
    /// # Errors
    /// The first line that does not parse.
    pub fn parse(text: &str, file: &str) -> Result<Script, ScriptError> {
        let mut actions = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = raw.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let action = parse_line(line).map_err(|problem| ScriptError {
                file: file.to_string(),
                line: i + 1,
                problem,
            })?;
            actions.push((i + 1, action));
        }
        Ok(Script { actions })
    }
}

/// A finite number.
fn num(s: &str, what: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{what} '{s}' is not a finite number")),
    }
}

fn on_off(s: &str) -> Result<bool, String> {
    match s {
        "on" | "true" | "1" => Ok(true),
        "off" | "false" | "0" => Ok(false),
        _ => Err(format!("'{s}' is not on or off")),
    }
}

fn parse_line(line: &str) -> Result<Action, String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    let (verb, args) = (words[0], &words[1..]);
    let want = |n: usize| {
        if args.len() == n {
            Ok(())
        } else {
            Err(format!(
                "'{verb}' takes {n} argument{} ({} given)",
                if n == 1 { "" } else { "s" },
                args.len()
            ))
        }
    };
    let count = |s: &str, what: &str| -> Result<u32, String> {
        s.parse::<u32>()
            .map_err(|_| format!("{what} '{s}' is not a whole number >= 0"))
    };
    // A path is the rest of the line, so it may hold spaces.
    let rest = || line[verb.len()..].trim();
    let path = |exts: &[&str]| -> Result<PathBuf, String> {
        let p = rest();
        if p.is_empty() {
            return Err(format!("'{verb}' needs a file"));
        }
        let ext = Path::new(p)
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        if !exts.is_empty() && !exts.contains(&ext.as_str()) {
            return Err(format!(
                "'{verb} {p}': the file must end in .{}",
                exts.join(" or .")
            ));
        }
        Ok(PathBuf::from(p))
    };
    Ok(match verb {
        "wait-frames" => {
            want(1)?;
            Action::WaitFrames(count(args[0], "frame count")?)
        }
        "wait-reference" => {
            want(1)?;
            Action::WaitReference(count(args[0], "samples per pixel")?.max(1))
        }
        "orbit" => {
            want(2)?;
            Action::Orbit(num(args[0], "yaw")?, num(args[1], "pitch")?)
        }
        "pan" => {
            want(2)?;
            Action::Pan(num(args[0], "dx")?, num(args[1], "dy")?)
        }
        "zoom" => {
            want(1)?;
            let f = num(args[0], "zoom factor")?;
            if f <= 0.0 {
                return Err(format!("zoom factor {f} must be > 0"));
            }
            Action::Zoom(f)
        }
        "reset-camera" => want(0).map(|_| Action::ResetCamera)?,
        "bundle-camera" => want(0).map(|_| Action::BundleCamera)?,
        "rotate-env" => {
            want(1)?;
            Action::RotateEnv(num(args[0], "angle")?)
        }
        "exposure" => {
            want(1)?;
            Action::Exposure(num(args[0], "exposure")?)
        }
        "sky" => {
            want(2)?;
            let e = num(args[0], "sun elevation")?;
            if !(0.0..=90.0).contains(&e) {
                return Err(format!("sun elevation {e} is not in [0, 90] degrees"));
            }
            Action::Sky(e, num(args[1], "sun azimuth")?)
        }
        "env" => Action::Env(path(&[])?),
        "bundle-env" => want(0).map(|_| Action::BundleEnv)?,
        "method" => {
            want(1)?;
            Action::Method(args[0].to_string())
        }
        "background" => {
            want(1)?;
            Action::Background(on_off(args[0])?)
        }
        "split" => {
            want(1)?;
            Action::Split(match args[0] {
                "off" => SplitMode::Off,
                "reference" | "on" => SplitMode::Reference,
                "heatmap" => SplitMode::Heatmap,
                s => return Err(format!("split '{s}' is not off, reference or heatmap")),
            })
        }
        "split-at" => {
            want(1)?;
            let f = num(args[0], "split fraction")?;
            if !(0.0..=1.0).contains(&f) {
                return Err(format!("split fraction {f} is not in [0, 1]"));
            }
            Action::SplitAt(f)
        }
        "screenshot" => Action::Screenshot(path(&["png", "exr"])?),
        "screenshot-window" => Action::ScreenshotWindow(path(&["png"])?),
        "print-state" => want(0).map(|_| Action::PrintState)?,
        "quit" => want(0).map(|_| Action::Quit)?,
        _ => return Err(format!("unknown action '{verb}' (actions: {SYNTAX})")),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_action_parses_and_comments_are_skipped() {
        let s = Script::parse(
            "# a comment\n\nwait-frames 3\norbit 30 -10\npan 0.1 0\nzoom 0.5\nreset-camera\n\
             bundle-camera\nrotate-env 90\nexposure -1.5\nsky 30 120\nenv my env.exr\n\
             bundle-env\nmethod hybrid\nbackground on\nsplit heatmap\nsplit-at 0.25\n\
             wait-reference 4\nscreenshot out/a.png\nscreenshot-window w.png\nprint-state\nquit\n",
            "s.txt",
        )
        .unwrap();
        let a: Vec<&Action> = s.actions.iter().map(|(_, a)| a).collect();
        assert_eq!(a.len(), 20);
        assert_eq!(s.actions[0].0, 3, "line numbers count comments and blanks");
        assert_eq!(a[1], &Action::Orbit(30.0, -10.0));
        assert_eq!(a[9], &Action::Env(PathBuf::from("my env.exr")));
        assert_eq!(a[13], &Action::Split(SplitMode::Heatmap));
        assert_eq!(a[19], &Action::Quit);
    }

    #[test]
    fn errors_name_the_file_the_line_and_the_problem() {
        for (text, line, needle) in [
            ("quit\nfly 3\n", 2, "unknown action 'fly'"),
            ("\norbit 30\n", 2, "takes 2 arguments (1 given)"),
            ("zoom -1", 1, "must be > 0"),
            ("rotate-env nan", 1, "not a finite number"),
            ("wait-frames -2", 1, "whole number"),
            ("screenshot a.jpg", 1, ".png or .exr"),
            ("screenshot-window a.exr", 1, ".png"),
            ("screenshot", 1, "needs a file"),
            ("sky 95 0", 1, "[0, 90]"),
            ("background maybe", 1, "on or off"),
        ] {
            let e = Script::parse(text, "x.script").unwrap_err();
            assert_eq!(e.line, line, "{text}");
            let m = e.to_string();
            assert!(m.starts_with(&format!("x.script:{line}: ")), "{m}");
            assert!(m.contains(needle), "{m} lacks {needle}");
        }
    }

    #[test]
    fn a_missing_script_file_is_named() {
        let e = Script::read(Path::new("/nonexistent/s.txt")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/s.txt"), "{e}");
    }
}
