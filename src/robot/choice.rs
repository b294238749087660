//! A robot a user names (`--robot`): the embedded ABB IRB 120 or a URDF file. Parsed once where
//! the request is read; a name that is neither is refused there, by name.

use super::Robot;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The embedded arm's name.
pub const EMBEDDED: &str = "irb120";

/// A robot named by a user: the embedded IRB 120 or a URDF file (in files and on the command
/// line, `irb120` or the path).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(into = "String", try_from = "String")]
pub enum RobotChoice {
    /// The embedded ABB IRB 120.
    #[default]
    Irb120,
    /// A URDF file.
    Urdf(PathBuf),
}

impl RobotChoice {
    /// The robot it names.
    pub fn load(&self) -> Result<Robot> {
        match self {
            RobotChoice::Irb120 => Ok(Robot::irb120()),
            RobotChoice::Urdf(p) => Robot::from_urdf_file(p),
        }
    }
    /// The file it reads, where it names one.
    pub fn file(&self) -> Option<&Path> {
        match self {
            RobotChoice::Irb120 => None,
            RobotChoice::Urdf(p) => Some(p),
        }
    }
    /// The same with a URDF path made absolute (against the working folder).
    pub fn absolute(self) -> RobotChoice {
        match self {
            RobotChoice::Urdf(p) => RobotChoice::Urdf(std::path::absolute(&p).unwrap_or(p)),
            other => other,
        }
    }
}

impl std::str::FromStr for RobotChoice {
    type Err = Error;
    fn from_str(s: &str) -> Result<RobotChoice> {
        match s {
            EMBEDDED => Ok(RobotChoice::Irb120),
            path if path.ends_with(".urdf") => Ok(RobotChoice::Urdf(PathBuf::from(path))),
            other => Err(Error::Invalid(format!("--robot '{other}': expected {EMBEDDED} or a .urdf path"))),
        }
    }
}

impl std::fmt::Display for RobotChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            RobotChoice::Irb120 => f.write_str(EMBEDDED),
            RobotChoice::Urdf(p) => write!(f, "{}", p.display()),
        }
    }
}

impl From<RobotChoice> for String {
    fn from(r: RobotChoice) -> String {
        r.to_string()
    }
}

impl TryFrom<String> for RobotChoice {
    type Error = Error;
    fn try_from(s: String) -> Result<RobotChoice> {
        s.parse()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_robot_is_the_embedded_arm_or_a_urdf_path_and_nothing_else() {
        assert_eq!("irb120".parse::<RobotChoice>().unwrap(), RobotChoice::Irb120);
        let u: RobotChoice = "arms/ur5.urdf".parse().unwrap();
        assert_eq!(u, RobotChoice::Urdf("arms/ur5.urdf".into()));
        assert_eq!(u.file(), Some(Path::new("arms/ur5.urdf")));
        assert_eq!(u.to_string().parse::<RobotChoice>().unwrap(), u);
        assert_eq!(serde_json::to_string(&RobotChoice::Irb120).unwrap(), "\"irb120\"");
        let e = "ur5".parse::<RobotChoice>().unwrap_err().to_string();
        assert!(e.contains("--robot 'ur5'") && e.contains("irb120 or a .urdf path"), "{e}");
        assert!(serde_json::from_str::<RobotChoice>("\"kuka\"").is_err());
        assert_eq!(RobotChoice::default().load().unwrap().dof(), 6);
    }
}
