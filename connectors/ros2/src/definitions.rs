//! The autocoder: ROS 2 action definitions found where a ROS 2 installation keeps them, turned
//! into the catalogue entries TRACE checks missions against before flight.
//!
//! Definitions are read from `share/<package>/action/<Name>.action` and
//! `share/<package>/msg/<Name>.msg` under each prefix of `AMENT_PREFIX_PATH`, and from the
//! directories a connector lists — each a prefix (holding `share/`), a `share/` directory, or a
//! package directory (holding `action/` or `msg/`; its name is the package's).
//!
//! Types: `bool` is `bool`; `float32` and `float64` are `f64`; `int64` is `int`; the other
//! integers (`byte`, `char`, `int8` … `uint64`) their width (`u8`, `i32`, …), refused outside
//! its range; strings are `string`; arrays and sequences lists; a message a nested object of
//! its fields. A field with a default value may be left out of a goal (the server fills the
//! default); one without must be written.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use connector_api::catalogue::{ActionSpec, Type, Width};

use crate::idl::{self, Base, Count, FieldType, IdlError, Part};

/// How deep messages may nest (a definition that contains itself is refused).
const MAX_DEPTH: usize = 32;

/// Where definitions are found.
#[derive(Clone, Debug, Default)]
pub struct Definitions {
    /// Package directories, by package name (the first found wins).
    packages: BTreeMap<String, PathBuf>,
    /// Where was looked, for messages.
    searched: Vec<PathBuf>,
}

/// One action's three parts, resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Action {
    /// `test_msgs/action/Fibonacci`
    pub ty: String,
    /// The goal's fields.
    pub goal: BTreeMap<String, Type>,
    /// The result's fields.
    pub result: BTreeMap<String, Type>,
    /// The feedback's fields.
    pub feedback: BTreeMap<String, Type>,
    /// Each part's fields with their types as `rclpy` names them (`int32`,
    /// `sequence<int32>`, `test_msgs/BasicTypes`), in order: goal, result, feedback.
    pub ros_types: [Vec<(String, String)>; 3],
    /// The result's string constants, value by name: the error codes a result field may carry
    /// (`string TOOL_STUCK="TOOL_STUCK"`).
    pub codes: BTreeMap<String, String>,
}

impl Definitions {
    /// The definitions under `AMENT_PREFIX_PATH`'s prefixes, then under `extra`.
    pub fn from_env(extra: &[PathBuf]) -> Definitions {
        let mut roots: Vec<PathBuf> = std::env::var_os("AMENT_PREFIX_PATH")
            .map(|v| std::env::split_paths(&v).collect())
            .unwrap_or_default();
        roots.extend(extra.iter().cloned());
        Definitions::new(&roots)
    }

    /// The definitions under `roots` (prefixes, `share/` directories or package directories).
    pub fn new(roots: &[PathBuf]) -> Definitions {
        let mut d = Definitions::default();
        for root in roots {
            d.searched.push(root.clone());
            let share = if root.join("share").is_dir() {
                root.join("share")
            } else {
                root.clone()
            };
            if is_package(root) {
                d.add(root);
                continue;
            }
            let Ok(entries) = std::fs::read_dir(&share) else {
                continue;
            };
            let mut dirs: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
            dirs.sort();
            for dir in dirs.iter().filter(|p| is_package(p)) {
                d.add(dir);
            }
        }
        d
    }

    fn add(&mut self, dir: &Path) {
        if let Some(name) = dir.file_name().and_then(|n| n.to_str()) {
            self.packages
                .entry(name.to_owned())
                .or_insert_with(|| dir.to_owned());
        }
    }

    /// The packages found, with their directories.
    pub fn packages(&self) -> &BTreeMap<String, PathBuf> {
        &self.packages
    }

    /// Every action definition found, as `package/action/Name`.
    pub fn actions(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (package, dir) in &self.packages {
            let Ok(entries) = std::fs::read_dir(dir.join("action")) else {
                continue;
            };
            let mut names: Vec<String> = entries
                .flatten()
                .filter_map(|e| {
                    let p = e.path();
                    (p.extension()? == "action")
                        .then(|| p.file_stem()?.to_str().map(str::to_owned))?
                })
                .collect();
            names.sort();
            out.extend(names.into_iter().map(|n| format!("{package}/action/{n}")));
        }
        out
    }

    /// Resolves the action of type `ty` (`package/action/Name`, or `package/Name`).
    pub fn action(&self, ty: &str) -> Result<Action, IdlError> {
        let (package, name) = match ty.split('/').collect::<Vec<_>>().as_slice() {
            [p, "action", n] | [p, n] => ((*p).to_owned(), (*n).to_owned()),
            _ => {
                return Err(IdlError {
                    file: ty.to_owned(),
                    line: 0,
                    reason: "an action type is `package/action/Name`".into(),
                });
            }
        };
        let (file, text) = self.read(&package, "action", &name, None)?;
        let parts = idl::parse(&text, &file, 3)?;
        let mut types = [Vec::new(), Vec::new(), Vec::new()];
        let mut maps = [BTreeMap::new(), BTreeMap::new(), BTreeMap::new()];
        for (k, part) in parts.iter().enumerate() {
            maps[k] = self.fields(part, &package, &file, 0)?;
            types[k] = part
                .fields
                .iter()
                .map(|f| (f.name.clone(), qualified(&f.ty, &package)))
                .collect();
        }
        let [goal, result, feedback] = maps;
        let codes = parts[1]
            .constants
            .iter()
            .filter(|c| matches!(c.ty.base, Base::String(_) | Base::WString(_)))
            .map(|c| (c.name.clone(), unquote(&c.value)))
            .collect();
        Ok(Action {
            ty: format!("{package}/action/{name}"),
            goal,
            result,
            feedback,
            ros_types: types,
            codes,
        })
    }

    /// The fields of message `package/name`, as `rclpy` names their types.
    pub fn message_types(
        &self,
        package: &str,
        name: &str,
    ) -> Result<Vec<(String, String)>, IdlError> {
        let (file, text) = self.read(package, "msg", name, None)?;
        let part = idl::parse(&text, &file, 1)?.remove(0);
        Ok(part
            .fields
            .iter()
            .map(|f| (f.name.clone(), qualified(&f.ty, package)))
            .collect())
    }

    /// A definition file's path and text; `from` is the field that needs it, for the error.
    fn read(
        &self,
        package: &str,
        kind: &str,
        name: &str,
        from: Option<(&str, usize)>,
    ) -> Result<(String, String), IdlError> {
        let (file, line) = from.unwrap_or((name, 0));
        let missing = |why: String| IdlError {
            file: file.to_owned(),
            line,
            reason: why,
        };
        let dir = self.packages.get(package).ok_or_else(|| {
            missing(format!(
                "no package `{package}` (for `{package}/{name}`) in {}",
                self.where_searched()
            ))
        })?;
        let path = dir.join(kind).join(format!("{name}.{kind}"));
        let text = std::fs::read_to_string(&path).map_err(|e| {
            missing(format!(
                "`{package}/{kind}/{name}`: {} cannot be read: {e}",
                path.display()
            ))
        })?;
        Ok((path.display().to_string(), text))
    }

    fn where_searched(&self) -> String {
        if self.searched.is_empty() {
            "no directory (AMENT_PREFIX_PATH is not set and the connector lists no `definitions`)"
                .to_owned()
        } else {
            self.searched
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        }
    }

    /// A part's fields as catalogue types.
    fn fields(
        &self,
        part: &Part,
        package: &str,
        file: &str,
        depth: usize,
    ) -> Result<BTreeMap<String, Type>, IdlError> {
        let mut out = BTreeMap::new();
        for f in &part.fields {
            let ty = self.field(&f.ty, package, file, f.line, depth)?;
            let ty = if f.default.is_some() {
                Type::Optional(Box::new(ty))
            } else {
                ty
            };
            out.insert(f.name.clone(), ty);
        }
        Ok(out)
    }

    fn field(
        &self,
        ty: &FieldType,
        package: &str,
        file: &str,
        line: usize,
        depth: usize,
    ) -> Result<Type, IdlError> {
        let one = match &ty.base {
            Base::Bool => Type::Bool,
            Base::Float32 | Base::Float64 => Type::Float,
            Base::Int64 => Type::Int,
            Base::Byte | Base::Char | Base::UInt8 => Type::Sized(Width::U8),
            Base::Int8 => Type::Sized(Width::I8),
            Base::Int16 => Type::Sized(Width::I16),
            Base::UInt16 => Type::Sized(Width::U16),
            Base::Int32 => Type::Sized(Width::I32),
            Base::UInt32 => Type::Sized(Width::U32),
            Base::UInt64 => Type::Sized(Width::U64),
            Base::String(_) | Base::WString(_) => Type::String,
            Base::Message { package: p, name } => {
                let p = p.as_deref().unwrap_or(package);
                if depth >= MAX_DEPTH {
                    return Err(IdlError {
                        file: file.to_owned(),
                        line,
                        reason: format!(
                            "`{p}/{name}` nests deeper than {MAX_DEPTH} messages (does it contain itself?)"
                        ),
                    });
                }
                let (inner_file, text) = self.read(p, "msg", name, Some((file, line)))?;
                let part = idl::parse(&text, &inner_file, 1)?.remove(0);
                Type::Object(self.fields(&part, p, &inner_file, depth + 1)?)
            }
        };
        Ok(match ty.count {
            Count::One => one,
            _ => Type::List(Box::new(one)),
        })
    }
}

/// Whether a directory holds a package's definitions.
fn is_package(dir: &Path) -> bool {
    dir.join("action").is_dir() || dir.join("msg").is_dir()
}

/// A type as `rclpy` names it, a message of the file's own package qualified with it.
fn qualified(ty: &FieldType, package: &str) -> String {
    match &ty.base {
        Base::Message {
            package: None,
            name,
        } => FieldType {
            base: Base::Message {
                package: Some(package.to_owned()),
                name: name.clone(),
            },
            count: ty.count,
        }
        .to_string(),
        _ => ty.to_string(),
    }
}

/// A string constant's value without its quotes.
fn unquote(v: &str) -> String {
    let v = v.trim();
    for q in ['"', '\''] {
        if let Some(inner) = v.strip_prefix(q).and_then(|r| r.strip_suffix(q)) {
            return inner.to_owned();
        }
    }
    v.to_owned()
}

impl Action {
    /// The catalogue entry of this action served as `name` (the resource a mission names)
    /// under the ROS 2 action `ros_name`; with an `error_field`, the error codes it may raise
    /// are the result's string constants.
    pub fn spec(&self, name: &str, ros_name: &str, error_field: Option<&str>) -> ActionSpec {
        let errors = match error_field {
            Some(field) => self
                .codes
                .iter()
                .map(|(constant, code)| (code.clone(), format!("`{field}` = {constant}")))
                .collect(),
            None => BTreeMap::new(),
        };
        ActionSpec {
            name: name.to_owned(),
            description: format!("ROS 2 action `{ros_name}` ({})", self.ty),
            goal: self.goal.clone(),
            result: self.result.clone(),
            feedback: self.feedback.clone(),
            errors,
            cost: None,
        }
    }
}

/// The catalogue of every action the definitions hold, each named by its type, served by
/// `server`; the first definition that cannot be read is the error.
pub fn catalogue(defs: &Definitions, server: &str) -> Result<connector_api::Catalogue, IdlError> {
    let mut actions = Vec::new();
    for ty in defs.actions() {
        actions.push(defs.action(&ty)?.spec(&ty, &ty, None));
    }
    Ok(connector_api::Catalogue {
        server: server.to_owned(),
        actions,
        ..connector_api::Catalogue::default()
    })
}

/// The catalogue a ROS 2 connector serves: one entry per resource its `actions` route to a ROS 2
/// action, named by the resource, from the action's definition (found under
/// `AMENT_PREFIX_PATH` and the connector's `definitions`).
pub fn catalogue_of(
    c: &connector_api::ConnectorConfig,
) -> Result<connector_api::Catalogue, IdlError> {
    let defs = Definitions::from_env(&c.ros2.definitions);
    let mut actions = Vec::new();
    for (resource, route) in &c.actions {
        if let connector_api::ActionRoute::Ros2(a) = route {
            actions.push(
                defs.action(&a.ty)?
                    .spec(resource, &a.action, a.error_field.as_deref()),
            );
        }
    }
    Ok(connector_api::Catalogue {
        server: c.server().to_owned(),
        actions,
        ..connector_api::Catalogue::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn package(files: &[(&str, &str)]) -> PathBuf {
        static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let root = std::env::temp_dir().join(format!("trace-ros2-defs-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        for (path, text) in files {
            let p = root.join(path);
            std::fs::create_dir_all(p.parent().expect("a folder")).expect("folder");
            std::fs::write(p, text).expect("file");
        }
        root
    }

    #[test]
    fn a_result_s_string_constants_are_the_codes_its_error_field_carries() {
        let root = package(&[
            (
                "dig_msgs/action/Dig.action",
                "int32 site_id\nfloat64 depth_cm 10.0\nSite site\n---\nstring TOOL_STUCK=\"TOOL_STUCK\"\n\
                 string HARD='HARD_MATERIAL'\nstring error_code\nfloat64 achieved_cm\n---\nfloat64 depth_cm",
            ),
            ("dig_msgs/msg/Site.msg", "uint8 id\nstring<=8 name"),
        ]);
        let defs = Definitions::new(std::slice::from_ref(&root));
        let a = defs.action("dig_msgs/action/Dig").expect("resolves");
        let spec = a.spec("excavation.excavate", "/dig", Some("error_code"));
        assert_eq!(
            spec.errors.keys().collect::<Vec<_>>(),
            ["HARD_MATERIAL", "TOOL_STUCK"]
        );
        assert_eq!(spec.goal["site_id"].to_string(), "i32");
        assert_eq!(spec.goal["depth_cm"].to_string(), "f64?");
        assert_eq!(spec.goal["site"].to_string(), "{id: u8, name: string}");
        assert!(a.spec("x", "/dig", None).errors.is_empty());
        let _ = std::fs::remove_dir_all(&root);
    }

    #[test]
    fn a_message_that_is_not_there_is_named_with_the_field_that_needs_it() {
        let root = package(&[(
            "dig_msgs/action/Dig.action",
            "int32 a\nPose pose\n---\n---\n",
        )]);
        let e = Definitions::new(std::slice::from_ref(&root))
            .action("dig_msgs/action/Dig")
            .expect_err("no Pose");
        assert!(e.file.ends_with("Dig.action") && e.line == 2, "{e}");
        assert!(e.reason.contains("dig_msgs/msg/Pose"), "{e}");
        let e = Definitions::new(std::slice::from_ref(&root))
            .action("nav_msgs/action/Go")
            .expect_err("no package");
        assert!(e.reason.contains("no package `nav_msgs`"), "{e}");
        let _ = std::fs::remove_dir_all(&root);
    }
}
