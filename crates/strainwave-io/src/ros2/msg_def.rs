//! ROS 2 message definitions (`ros2msg` text, as MCAP stores them and as rosbag2 keeps
//! them in `message_definitions`), parsed into a flat table of types.
//!
//! The text is the root type's fields, then each nested type after a line of `=` and a
//! `MSG: pkg/Type` line. A field line is `TYPE NAME [DEFAULT]`; `TYPE` is a primitive, a
//! nested type (`pkg/Type`, `pkg/msg/Type`, or `Type` of the same package) and an optional
//! array suffix: `[N]` fixed, `[]` or `[<=N]` a sequence. Constants (`TYPE NAME=VALUE`)
//! and comments are left out. Types missing from the text are looked up among a few
//! built-in definitions (headers, times, joint states, wrenches), which also serve SQLite
//! bags that store no definitions.

/// A primitive field type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Prim {
    /// `bool`, 1 byte.
    Bool,
    /// `int8`.
    I8,
    /// `uint8`, `byte`, `char`.
    U8,
    /// `int16`.
    I16,
    /// `uint16`.
    U16,
    /// `int32`.
    I32,
    /// `uint32`.
    U32,
    /// `int64`.
    I64,
    /// `uint64`.
    U64,
    /// `float32`.
    F32,
    /// `float64`.
    F64,
    /// `string` (bounded or not).
    Str,
}

impl Prim {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "bool" => Self::Bool,
            "int8" => Self::I8,
            "uint8" | "byte" | "char" => Self::U8,
            "int16" => Self::I16,
            "uint16" => Self::U16,
            "int32" => Self::I32,
            "uint32" => Self::U32,
            "int64" => Self::I64,
            "uint64" => Self::U64,
            "float32" => Self::F32,
            "float64" => Self::F64,
            _ if s == "string" || s.starts_with("string<=") => Self::Str,
            _ => return None,
        })
    }

    /// Bytes on the wire (a string's length prefix for `Str`).
    pub fn size(self) -> usize {
        match self {
            Self::Bool | Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 | Self::Str => 4,
            Self::I64 | Self::U64 | Self::F64 => 8,
        }
    }
}

/// What a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ty {
    /// A primitive.
    Prim(Prim),
    /// A nested type, by index into [`MsgDef::types`].
    Nested(usize),
}

/// How many of them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arity {
    /// One value.
    One,
    /// A fixed-size array (no length on the wire).
    Fixed(usize),
    /// A sequence (a `uint32` length first).
    Seq,
}

/// One field of a type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    /// Its name.
    pub name: String,
    /// Its type.
    pub ty: Ty,
    /// Single, array or sequence.
    pub arity: Arity,
}

/// One message type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MsgType {
    /// `pkg/Type` (without `/msg/`).
    pub name: String,
    /// Fields in wire order.
    pub fields: Vec<Field>,
    /// Fewest bytes one value takes on the wire (0: it holds no value at all).
    pub min_bytes: usize,
}

/// A parsed definition: the root is `types[0]`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MsgDef {
    /// Every type reachable from the root.
    pub types: Vec<MsgType>,
}

/// Nesting deeper than this is refused (it also stops a type that contains itself).
pub const MAX_DEPTH: usize = 32;

/// Built-in definitions for types a bag may not spell out.
const BUILTIN: &[(&str, &str)] = &[
    ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec"),
    ("builtin_interfaces/Duration", "int32 sec\nuint32 nanosec"),
    ("std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id"),
    ("std_msgs/Float64", "float64 data"),
    ("std_msgs/Float32", "float32 data"),
    ("std_msgs/Float64MultiArray", "std_msgs/MultiArrayLayout layout\nfloat64[] data"),
    ("std_msgs/MultiArrayLayout", "std_msgs/MultiArrayDimension[] dim\nuint32 data_offset"),
    ("std_msgs/MultiArrayDimension", "string label\nuint32 size\nuint32 stride"),
    (
        "sensor_msgs/JointState",
        "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort",
    ),
    (
        "control_msgs/DynamicJointState",
        "std_msgs/Header header\nstring[] joint_names\ncontrol_msgs/InterfaceValue[] interface_values",
    ),
    ("control_msgs/InterfaceValue", "string[] interface_names\nfloat64[] values"),
    ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z"),
    ("geometry_msgs/Wrench", "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque"),
    ("geometry_msgs/WrenchStamped", "std_msgs/Header header\ngeometry_msgs/Wrench wrench"),
];

/// A definition that cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum DefError {
    /// A field type that is neither primitive nor defined.
    #[error("type `{0}` is not defined in the schema")]
    Unknown(String),
    /// A field line that does not parse.
    #[error("cannot read the field line `{0}`")]
    Line(String),
    /// Types nested too deep (or recursive).
    #[error("types nested deeper than {MAX_DEPTH} levels")]
    TooDeep,
}

/// `pkg/msg/Type` → `pkg/Type`.
pub fn normalize(name: &str) -> String {
    name.trim().replacen("/msg/", "/", 1)
}

fn builtin(name: &str) -> Option<&'static str> {
    BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
}

/// The built-in text of a type, if there is one (for SQLite bags without definitions).
pub fn builtin_definition(type_name: &str) -> Option<&'static str> {
    builtin(&normalize(type_name))
}

/// One field line before the type is resolved.
#[derive(Clone)]
struct RawField {
    ty: String,
    name: String,
    arity: Arity,
}

fn parse_line(line: &str) -> Result<Option<RawField>, DefError> {
    let line = line.split('#').next().unwrap_or("").trim();
    if line.is_empty() {
        return Ok(None);
    }
    let mut tokens = line.split_whitespace();
    let (Some(ty), Some(name)) = (tokens.next(), tokens.next()) else {
        return Err(DefError::Line(line.chars().take(80).collect()));
    };
    // Constants: `int32 X=1` or `int32 X = 1`.
    if name.contains('=') || tokens.next().is_some_and(|t| t.starts_with('=')) {
        return Ok(None);
    }
    let (base, arity) = match ty.find('[') {
        None => (ty, Arity::One),
        Some(i) => {
            let inside = ty[i + 1..].strip_suffix(']').ok_or_else(|| DefError::Line(line.into()))?;
            let arity = if inside.is_empty() || inside.starts_with("<=") {
                Arity::Seq
            } else {
                Arity::Fixed(inside.parse().map_err(|_| DefError::Line(line.into()))?)
            };
            (&ty[..i], arity)
        }
    };
    Ok(Some(RawField { ty: base.to_string(), name: name.to_string(), arity }))
}

impl MsgDef {
    /// Parses the text of `root_name` (its nested types after `MSG:` lines).
    pub fn parse(root_name: &str, text: &str) -> Result<Self, DefError> {
        let mut blocks: Vec<(String, Vec<RawField>)> = vec![(normalize(root_name), Vec::new())];
        for line in text.lines() {
            let trimmed = line.trim();
            if trimmed.len() >= 3 && trimmed.bytes().all(|b| b == b'=') {
                continue;
            }
            if let Some(name) = trimmed.strip_prefix("MSG:") {
                blocks.push((normalize(name), Vec::new()));
                continue;
            }
            if let Some(f) = parse_line(line)? {
                if let Some(last) = blocks.last_mut() {
                    last.1.push(f);
                }
            }
        }
        // An empty text names a built-in type (or a type with no fields).
        if blocks.len() == 1 && blocks[0].1.is_empty() {
            if let Some(t) = builtin(&blocks[0].0) {
                blocks[0].1 = t.lines().filter_map(|l| parse_line(l).ok().flatten()).collect();
            }
        }
        let mut def = MsgDef { types: Vec::new() };
        let root = blocks[0].clone();
        def.resolve(root, &blocks, 0)?;
        Ok(def)
    }

    /// Adds `block` as a type and resolves its nested types depth first; returns its index.
    fn resolve(
        &mut self,
        block: (String, Vec<RawField>),
        blocks: &[(String, Vec<RawField>)],
        depth: usize,
    ) -> Result<usize, DefError> {
        if depth > MAX_DEPTH {
            return Err(DefError::TooDeep);
        }
        let (name, raw) = block;
        let index = self.types.len();
        self.types.push(MsgType { name: name.clone(), fields: Vec::new(), min_bytes: 0 });
        let package = name.split('/').next().unwrap_or("").to_string();
        let mut fields = Vec::with_capacity(raw.len());
        for f in raw {
            let ty = match Prim::parse(&f.ty) {
                Some(p) => Ty::Prim(p),
                None => Ty::Nested(self.nested(&f.ty, &package, blocks, depth)?),
            };
            fields.push(Field { name: f.name, ty, arity: f.arity });
        }
        // An empty struct is one byte in CDR.
        let min_bytes = if fields.is_empty() {
            1
        } else {
            fields.iter().fold(0usize, |sum, f| {
                sum.saturating_add(match f.arity {
                    Arity::One => self.min_bytes(f.ty),
                    Arity::Fixed(n) => n.saturating_mul(self.min_bytes(f.ty)),
                    Arity::Seq => 4,
                })
            })
        };
        self.types[index].fields = fields;
        self.types[index].min_bytes = min_bytes;
        Ok(index)
    }

    /// Fewest bytes one value of `ty` takes on the wire.
    pub fn min_bytes(&self, ty: Ty) -> usize {
        match ty {
            Ty::Prim(p) => p.size(),
            Ty::Nested(i) => self.types[i].min_bytes,
        }
    }

    fn nested(
        &mut self,
        ty: &str,
        package: &str,
        blocks: &[(String, Vec<RawField>)],
        depth: usize,
    ) -> Result<usize, DefError> {
        let full = match ty {
            "time" => "builtin_interfaces/Time".to_string(),
            "duration" => "builtin_interfaces/Duration".to_string(),
            "Header" => "std_msgs/Header".to_string(),
            t if t.contains('/') => normalize(t),
            t => format!("{package}/{t}"),
        };
        // Each type is resolved once and shared by its uses (copies would grow
        // exponentially with the depth); one still being resolved contains itself.
        if let Some(i) = self.types.iter().position(|t| t.name == full) {
            let resolving = self.types[i].fields.is_empty() && self.types[i].min_bytes == 0;
            return if resolving { Err(DefError::TooDeep) } else { Ok(i) };
        }
        let short = full.rsplit('/').next().unwrap_or(&full).to_string();
        let found = blocks
            .iter()
            .position(|(n, _)| *n == full)
            .or_else(|| blocks.iter().position(|(n, _)| n.rsplit('/').next() == Some(short.as_str())));
        let raw: Vec<RawField> = match found {
            Some(i) => blocks[i].1.clone(),
            None => match builtin(&full) {
                Some(t) => t.lines().filter_map(|l| parse_line(l).ok().flatten()).collect(),
                None => return Err(DefError::Unknown(ty.to_string())),
            },
        };
        self.resolve((full, raw), blocks, depth + 1)
    }

    /// The root type.
    pub fn root(&self) -> &MsgType {
        &self.types[0]
    }

    /// Whether the root's first field is a `std_msgs/Header` named `header`.
    pub fn has_header(&self) -> bool {
        match self.root().fields.first() {
            Some(Field { name, ty: Ty::Nested(i), arity: Arity::One }) => {
                name == "header" && self.types[*i].name == "std_msgs/Header"
            }
            _ => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_arrays_constants_and_comments() {
        let text = "# a comment\nint32 MODE_A=1\nint32 MODE_B = 2\nstd_msgs/Header header\nfloat64[3] xyz  # fixed\nInner[<=4] inner\nstring<=8 tag\n===\nMSG: my_pkg/Inner\nuint8[] raw\nfloat32 k 0.5\n";
        let d = MsgDef::parse("my_pkg/msg/Outer", text).unwrap();
        let root = d.root();
        assert_eq!(root.name, "my_pkg/Outer");
        let names: Vec<&str> = root.fields.iter().map(|f| f.name.as_str()).collect();
        assert_eq!(names, ["header", "xyz", "inner", "tag"]);
        assert_eq!(root.fields[1].arity, Arity::Fixed(3));
        assert_eq!(root.fields[2].arity, Arity::Seq);
        assert_eq!(root.fields[3].ty, Ty::Prim(Prim::Str));
        assert!(d.has_header());
        let Ty::Nested(i) = root.fields[2].ty else { panic!("inner is nested") };
        assert_eq!(d.types[i].name, "my_pkg/Inner");
        assert_eq!(d.types[i].fields[1].ty, Ty::Prim(Prim::F32));
    }

    #[test]
    fn empty_text_of_a_known_type_uses_the_builtin() {
        let d = MsgDef::parse("geometry_msgs/msg/WrenchStamped", "").unwrap();
        assert!(d.has_header());
        assert_eq!(d.root().fields[1].name, "wrench");
    }

    #[test]
    fn a_type_used_many_times_is_resolved_once() {
        // 24 levels, each using the next twice: 2^24 uses. Before, each use was a copy
        // (gigabytes); now 25 types.
        let mut text = String::from("L1 a\nL1 b\n");
        for k in 1..24 {
            text += &format!("===\nMSG: p/L{k}\nL{} a\nL{} b\n", k + 1, k + 1);
        }
        text += "===\nMSG: p/L24\nfloat64 v\n";
        let d = MsgDef::parse("p/Root", &text).unwrap();
        assert_eq!(d.types.len(), 25);
        assert_eq!(d.root().min_bytes, 8 << 24);
        assert_eq!(d.min_bytes(d.root().fields[0].ty), 8 << 23);
    }

    #[test]
    fn unknown_and_recursive_types_are_errors() {
        assert_eq!(MsgDef::parse("a/B", "c/D x").unwrap_err(), DefError::Unknown("c/D".into()));
        assert_eq!(MsgDef::parse("a/B", "B self").unwrap_err(), DefError::TooDeep);
        let mutual = "C c\n===\nMSG: a/C\nB b\n";
        assert_eq!(MsgDef::parse("a/B", mutual).unwrap_err(), DefError::TooDeep);
        assert!(matches!(MsgDef::parse("a/B", "float64[x] v"), Err(DefError::Line(_))));
    }
}
