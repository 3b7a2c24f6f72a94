//! Typed DMIS statements of the supported subset, and their printing.
//!
//! Values are kept as the program writes them (its units, its label names); the semantic model
//! ([`crate::model`]) converts them. `Display` prints a statement in canonical DMIS (upper-case
//! words, no blanks, numbers in their shortest exact form), so that parsing the printed text gives
//! the same statement back: `parse(print(parse(p))) == parse(p)`.

use std::fmt::{self, Display, Formatter, Write as _};

/// The kinds of label of the subset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LabelKind {
    /// Nominal feature `F()`.
    F,
    /// Actual feature `FA()`.
    Fa,
    /// Coordinate system (datum reference frame) `D()`.
    D,
    /// Actual coordinate system `DA()` (DMIS 3 also names datums so).
    Da,
    /// Datum `DAT()` (DMIS 4 and later).
    Dat,
    /// Tolerance `T()`.
    T,
    /// Actual tolerance `TA()`.
    Ta,
    /// Sensor `S()`.
    S,
    /// Actual (calibrated) sensor `SA()`.
    Sa,
    /// Input/output device `DID()`.
    Did,
}

impl LabelKind {
    /// The kind whose label prefix is `p` (`F`, `FA`, `DAT`, ..., upper case).
    pub fn from_prefix(p: &str) -> Option<LabelKind> {
        Some(match p {
            "F" => LabelKind::F,
            "FA" => LabelKind::Fa,
            "D" => LabelKind::D,
            "DA" => LabelKind::Da,
            "DAT" => LabelKind::Dat,
            "T" => LabelKind::T,
            "TA" => LabelKind::Ta,
            "S" => LabelKind::S,
            "SA" => LabelKind::Sa,
            "DID" => LabelKind::Did,
            _ => return None,
        })
    }
    /// The label prefix as DMIS spells it (`F`, `FA`, `DAT`, ...).
    pub fn prefix(self) -> &'static str {
        match self {
            LabelKind::F => "F",
            LabelKind::Fa => "FA",
            LabelKind::D => "D",
            LabelKind::Da => "DA",
            LabelKind::Dat => "DAT",
            LabelKind::T => "T",
            LabelKind::Ta => "TA",
            LabelKind::S => "S",
            LabelKind::Sa => "SA",
            LabelKind::Did => "DID",
        }
    }
}

/// A label: `F(A_CIRCLE)`. Names compare case-insensitively in the semantic model ([`Label::key`]).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Label {
    /// The label's kind (its prefix).
    pub kind: LabelKind,
    /// The label's name as written.
    pub name: String,
}

impl Label {
    /// A label of `kind` called `name` (kept as written).
    pub fn new(kind: LabelKind, name: &str) -> Label {
        Label { kind, name: name.to_string() }
    }
    /// The name upper-cased: the identity of what the label names.
    pub fn key(&self) -> String {
        self.name.to_ascii_uppercase()
    }
}

impl Display for Label {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        write!(f, "{}({})", self.kind.prefix(), self.name)
    }
}

macro_rules! words {
    ($(#[$m:meta])* $name:ident { $($v:ident = $s:literal),* $(,)? }) => {
        $(#[$m])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum $name { $(#[doc = concat!("The DMIS word `", $s, "`.")] $v),* }
        impl $name {
            /// Every word of this kind, in order.
            pub const ALL: &'static [$name] = &[$($name::$v),*];
            /// The word as DMIS spells it (upper case).
            pub fn word(self) -> &'static str {
                match self { $($name::$v => $s),* }
            }
            /// The value spelled `w` (upper case), if `w` is a word of this kind.
            pub fn from_word(w: &str) -> Option<$name> {
                match w { $($s => Some($name::$v),)* _ => None }
            }
        }
        impl Display for $name {
            fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result { f.write_str(self.word()) }
        }
    };
}

words!(
    /// Length unit of `UNITS`.
    LengthUnit { Mm = "MM", Cm = "CM", M = "M", Inch = "INCH", Feet = "FEET" }
);
words!(
    /// Angle unit of `UNITS`.
    AngleUnit { AngDec = "ANGDEC", AngRad = "ANGRAD", AngDms = "ANGDMS" }
);
words!(
    /// Temperature unit of `UNITS` (DMIS 4 and later).
    TempUnit { TempC = "TEMPC", TempF = "TEMPF" }
);
words!(
    /// Feature types of `FEAT`, `MEAS` and `CONST`.
    FeatType {
        Point = "POINT",
        Plane = "PLANE",
        Line = "LINE",
        Circle = "CIRCLE",
        Cylndr = "CYLNDR",
        Sphere = "SPHERE",
        Cone = "CONE",
    }
);
words!(
    /// Inner (hole) or outer (boss) feature.
    Side { Inner = "INNER", Outer = "OUTER" }
);
words!(
    /// The speeds of `FEDRAT`.
    FeedKind { MesVel = "MESVEL", PosVel = "POSVEL", ScnVel = "SCNVEL" }
);
words!(
    /// The units of `FEDRAT`.
    FeedUnit {
        Mpm = "MPM",
        Mmps = "MMPS",
        Ipm = "IPM",
        Ips = "IPS",
        Pcent = "PCENT",
        High = "HIGH",
        Low = "LOW",
        Defalt = "DEFALT",
    }
);
words!(
    /// The words of `MODE`.
    ModeWord { Auto = "AUTO", Prog = "PROG", Man = "MAN" }
);
words!(
    /// Axis and origin words of `DATSET`.
    DatsetWord {
        XDir = "XDIR",
        YDir = "YDIR",
        ZDir = "ZDIR",
        XOrig = "XORIG",
        YOrig = "YORIG",
        ZOrig = "ZORIG",
    }
);
words!(
    /// Origins moved by `TRANS`.
    Origin { XOrig = "XORIG", YOrig = "YORIG", ZOrig = "ZORIG" }
);
words!(
    /// Axes of `ROTATE`.
    RotAxis { XAxis = "XAXIS", YAxis = "YAXIS", ZAxis = "ZAXIS" }
);
words!(
    /// Directions a feature sets in `ROTATE/…,FA(x),XDIR`.
    AxisDir { XDir = "XDIR", YDir = "YDIR", ZDir = "ZDIR" }
);
words!(
    /// Material condition of a position tolerance.
    MatCond { Rfs = "RFS", Mmc = "MMC", Lmc = "LMC" }
);
words!(
    /// Direction of a `DISTB` tolerance.
    DistAxis { XAxis = "XAXIS", YAxis = "YAXIS", ZAxis = "ZAXIS", Pt2Pt = "PT2PT" }
);
words!(
    /// Destinations of `TEXT`.
    TextKind { Oper = "OPER", Outfil = "OUTFIL", Man = "MAN", Query = "QUERY" }
);
words!(
    /// Kinds of `DEVICE`.
    DeviceKind { Stor = "STOR", Print = "PRINT", Term = "TERM", Comm = "COMM" }
);

/// Three numbers (a point or a direction as written).
pub type Xyz = [f64; 3];

/// The nominal geometry of `FEAT` (Cartesian, as the program writes it).
#[derive(Debug, Clone, PartialEq)]
pub enum FeatGeom {
    /// `POINT,CART,x,y,z,i,j,k`: a surface point and its normal.
    Point {
        /// The point, program frame and units.
        p: Xyz,
        /// The surface normal.
        n: Xyz,
    },
    /// `PLANE,CART,x,y,z,i,j,k`.
    Plane {
        /// A point of the plane, program frame and units.
        p: Xyz,
        /// The plane's normal.
        n: Xyz,
    },
    /// `LINE,UNBND,CART,x,y,z,i,j,k[,pi,pj,pk]` (point, direction, plane normal).
    LineUnbnd {
        /// A point of the line, program frame and units.
        p: Xyz,
        /// The line's direction.
        dir: Xyz,
        /// The normal of the plane the line lies in, when given.
        plane: Option<Xyz>,
    },
    /// `LINE,BND,CART,x1,y1,z1,x2,y2,z2[,pi,pj,pk]`.
    LineBnd {
        /// Start point, program frame and units.
        p1: Xyz,
        /// End point, program frame and units.
        p2: Xyz,
        /// The normal of the plane the line lies in, when given.
        plane: Option<Xyz>,
    },
    /// `CIRCLE,INNER|OUTER,CART,x,y,z,i,j,k,diam`.
    Circle {
        /// Hole or boss.
        side: Side,
        /// Centre, program frame and units.
        c: Xyz,
        /// Normal of the circle's plane.
        n: Xyz,
        /// Diameter, program units.
        diam: f64,
    },
    /// `CYLNDR,INNER|OUTER,CART,x,y,z,i,j,k,diam[,length]`.
    Cylndr {
        /// Hole or boss.
        side: Side,
        /// A point on the axis, program frame and units.
        p: Xyz,
        /// Axis direction.
        axis: Xyz,
        /// Diameter, program units.
        diam: f64,
        /// Length along the axis, program units, when given.
        length: Option<f64>,
    },
    /// `SPHERE,INNER|OUTER,CART,x,y,z[,i,j,k],diam`.
    Sphere {
        /// Hollow or solid.
        side: Side,
        /// Centre, program frame and units.
        c: Xyz,
        /// The direction the sphere is accessible from, when given.
        n: Option<Xyz>,
        /// Diameter, program units.
        diam: f64,
    },
    /// `CONE,INNER|OUTER,CART,x,y,z,i,j,k,angle` (apex, axis from the apex into the cone,
    /// included angle).
    Cone {
        /// Hole or boss.
        side: Side,
        /// Apex, program frame and units.
        apex: Xyz,
        /// Axis from the apex into the cone.
        axis: Xyz,
        /// Included angle, program angle units.
        angle: f64,
    },
}

impl FeatGeom {
    /// The `FEAT` type word of this geometry.
    pub fn feat_type(&self) -> FeatType {
        match self {
            FeatGeom::Point { .. } => FeatType::Point,
            FeatGeom::Plane { .. } => FeatType::Plane,
            FeatGeom::LineUnbnd { .. } | FeatGeom::LineBnd { .. } => FeatType::Line,
            FeatGeom::Circle { .. } => FeatType::Circle,
            FeatGeom::Cylndr { .. } => FeatType::Cylndr,
            FeatGeom::Sphere { .. } => FeatType::Sphere,
            FeatGeom::Cone { .. } => FeatType::Cone,
        }
    }
}

/// `SNSET` items.
#[derive(Debug, Clone, PartialEq)]
pub enum Snset {
    /// `APPRCH,dist`: approach distance before a point, program units.
    Apprch(f64),
    /// `RETRCT,dist`: retract distance after a point, program units.
    Retrct(f64),
    /// `SEARCH,dist`: search distance beyond a point, program units.
    Search(f64),
    /// `DEPTH,dist`: depth of a feature's points below its top, program units.
    Depth(f64),
    /// `CLRSRF,dist` or `CLRSRF,F(plane),dist`.
    Clrsrf(Option<Label>, f64),
    /// `CLRSRF,OFF`.
    ClrsrfOff,
}

/// `GOTO`.
#[derive(Debug, Clone, PartialEq)]
pub enum Goto {
    /// `GOTO/x,y,z`.
    Abs(Xyz),
    /// `GOTO/INCR,dist,i,j,k`.
    Incr {
        /// Distance to move, program units.
        dist: f64,
        /// Direction to move along.
        dir: Xyz,
    },
}

/// How `CONST` builds a feature.
#[derive(Debug, Clone, PartialEq)]
pub enum ConstMethod {
    /// `BF,FA(a),FA(b),…`: least-squares best fit through actual features' points.
    Bf(Vec<Label>),
    /// `INTOF,FA(a),FA(b)`: intersection.
    Intof(Label, Label),
    /// `PROJCT,FA(a),FA(b)`: `a` projected onto the plane `b`.
    Projct(Label, Label),
    /// `MIDPT,FA(a),FA(b)`: the point midway between two features' positions.
    Midpt(Label, Label),
}

/// `DATSET`.
#[derive(Debug, Clone, PartialEq)]
pub enum Datset {
    /// `DATSET/MCS`: the machine coordinate system.
    Mcs,
    /// `DATSET/DAT(A),ZDIR,ZORIG,DAT(B),XDIR,YORIG,…`.
    Datums(Vec<(Label, Vec<DatsetWord>)>),
}

/// What `TRANS` moves an origin to.
#[derive(Debug, Clone, PartialEq)]
pub enum TransBy {
    /// A value, program units.
    Value(f64),
    /// The position of an actual feature.
    Feature(Label),
}

/// What `ROTATE` turns by.
#[derive(Debug, Clone, PartialEq)]
pub enum RotateBy {
    /// An angle in the program's angle unit.
    Angle(f64),
    /// A feature whose direction becomes the given axis.
    Feature(Label, AxisDir),
}

/// `TOL` definitions.
#[derive(Debug, Clone, PartialEq)]
pub enum Tol {
    /// `FLAT,zone`: flatness, program units.
    Flat(f64),
    /// `STRGHT,zone`: straightness, program units.
    Strght(f64),
    /// `CIRLTY,zone`: circularity, program units.
    Cirlty(f64),
    /// `CYLCTY,zone`: cylindricity, program units.
    Cylcty(f64),
    /// `DIAM,lotol,uptol`: deviations from nominal.
    Diam {
        /// Lower deviation from the nominal diameter, program units.
        lo: f64,
        /// Upper deviation from the nominal diameter, program units.
        hi: f64,
    },
    /// `RAD,lotol,uptol`.
    Rad {
        /// Lower deviation from the nominal radius, program units.
        lo: f64,
        /// Upper deviation from the nominal radius, program units.
        hi: f64,
    },
    /// `POS,2D|3D,zone,RFS|MMC|LMC[,DAT(A),…]`.
    Pos {
        /// `3D` (a spherical zone) rather than `2D` (a cylindrical zone).
        three_d: bool,
        /// Diameter of the tolerance zone, program units.
        zone: f64,
        /// Material condition.
        cond: MatCond,
        /// The datums of the reference frame, in order.
        datums: Vec<Label>,
    },
    /// `PERP,zone,DAT(A)`.
    Perp {
        /// Width of the tolerance zone, program units.
        zone: f64,
        /// The datum the feature is perpendicular to.
        datum: Label,
    },
    /// `PARLEL,zone,DAT(A)`.
    Parlel {
        /// Width of the tolerance zone, program units.
        zone: f64,
        /// The datum the feature is parallel to.
        datum: Label,
    },
    /// `ANGLB,angle,lotol,uptol`.
    Anglb {
        /// Nominal angle, program angle units.
        angle: f64,
        /// Lower deviation, program angle units.
        lo: f64,
        /// Upper deviation, program angle units.
        hi: f64,
    },
    /// `DISTB,NOMINL,dist,lotol,uptol[,XAXIS|YAXIS|ZAXIS|PT2PT]`.
    Distb {
        /// Nominal distance, program units.
        dist: f64,
        /// Lower deviation, program units.
        lo: f64,
        /// Upper deviation, program units.
        hi: f64,
        /// The direction the distance is measured along (`None`: point to point).
        axis: Option<DistAxis>,
    },
}

impl Tol {
    /// The minor word.
    pub fn word(&self) -> &'static str {
        match self {
            Tol::Flat(_) => "FLAT",
            Tol::Strght(_) => "STRGHT",
            Tol::Cirlty(_) => "CIRLTY",
            Tol::Cylcty(_) => "CYLCTY",
            Tol::Diam { .. } => "DIAM",
            Tol::Rad { .. } => "RAD",
            Tol::Pos { .. } => "POS",
            Tol::Perp { .. } => "PERP",
            Tol::Parlel { .. } => "PARLEL",
            Tol::Anglb { .. } => "ANGLB",
            Tol::Distb { .. } => "DISTB",
        }
    }
}

/// One statement of the subset.
#[derive(Debug, Clone, PartialEq)]
pub enum Statement {
    /// `DMISMN/'title',version`: the program's start.
    Dmismn {
        /// The program's title.
        title: String,
        /// The DMIS version the program declares.
        version: Option<f64>,
    },
    /// `DMISMD/'title',version`: a module's start.
    Dmismd {
        /// The module's title.
        title: String,
        /// The DMIS version the module declares.
        version: Option<f64>,
    },
    /// `ENDFIL`: the end of the program.
    Endfil,
    /// `FILNAM/'name',version`: the program's name.
    Filnam {
        /// The name.
        name: String,
        /// The DMIS version, when given.
        version: Option<f64>,
    },
    /// `UNITS/length,angle[,temp]`.
    Units {
        /// The length unit of the statements that follow.
        length: LengthUnit,
        /// The angle unit of the statements that follow.
        angle: AngleUnit,
        /// The temperature unit, when given.
        temp: Option<TempUnit>,
    },
    /// `DISPLY/OFF` or `DISPLY/TERM,DMIS,STOR,DMIS,…`: words and device labels.
    Disply(Vec<DisplyItem>),
    /// `PRCOMP/ON|OFF`: probe compensation on (`true`) or off.
    Prcomp(bool),
    /// `MODE/...`: the execution mode words.
    Mode(Vec<ModeWord>),
    /// `FEDRAT/kind,unit[,value]`: a speed.
    Fedrat {
        /// Which speed (measuring, positioning, scanning).
        kind: FeedKind,
        /// The unit of `value`.
        unit: FeedUnit,
        /// The speed, in `unit` (none for `HIGH`, `LOW`, `DEFALT`).
        value: Option<f64>,
    },
    /// `SNSET/...`: a probing parameter.
    Snset(Snset),
    /// `S(l)=SNSDEF/PROBE,FIXED,CART,x,y,z,i,j,k,diam`: a fixed probe, its tip offset from the
    /// probe mount, its direction and its tip diameter.
    Snsdef {
        /// The sensor's label `S(l)`.
        label: Label,
        /// Tip offset from the probe mount, program units.
        offset: Xyz,
        /// Probe direction.
        dir: Xyz,
        /// Tip diameter, program units.
        diam: f64,
    },
    /// `SNSLCT/S(l)`: select a sensor.
    Snslct(Label),
    /// `SNSMNT/XVEC,i,j,k,ZVEC,i,j,k,MNTLEN,x,y,z`.
    Snsmnt {
        /// The mount's X direction.
        xvec: Xyz,
        /// The mount's Z direction.
        zvec: Xyz,
        /// The mount's offset, program units.
        mntlen: Xyz,
    },
    /// `GOTO/...`: a move.
    Goto(Goto),
    /// `F(l)=FEAT/...`: a nominal feature.
    Feat {
        /// The feature's label.
        label: Label,
        /// Its nominal geometry.
        geom: FeatGeom,
    },
    /// `F(l)=MEAS/type,F(l),n`: start measuring a feature.
    Meas {
        /// The feature type.
        ftype: FeatType,
        /// The nominal feature measured.
        feature: Label,
        /// The number of points to measure.
        n: u32,
    },
    /// `ENDMES`: the end of a measurement block.
    Endmes,
    /// `PTMEAS/CART,x,y,z[,i,j,k]`.
    Ptmeas {
        /// The nominal point, program frame and units.
        p: Xyz,
        /// The approach direction (the surface normal), when given.
        n: Option<Xyz>,
    },
    /// `F(l)=CONST/type,F(l),method`: construct a feature from others.
    Const {
        /// The constructed feature's type.
        ftype: FeatType,
        /// The constructed feature's label.
        feature: Label,
        /// How it is constructed.
        method: ConstMethod,
    },
    /// `DAT(A)=DATDEF/FA(x)` (`assigned`) or DMIS 3's `DATDEF/FA(x),DA(A)`.
    Datdef {
        /// The datum's label.
        datum: Label,
        /// The actual feature that defines it.
        feature: Label,
        /// Whether written as an assignment `DAT(A)=DATDEF/FA(x)`.
        assigned: bool,
    },
    /// `D(l)=DATSET/...`: a coordinate system from datums.
    Datset {
        /// The coordinate system's label.
        label: Label,
        /// How it is built.
        def: Datset,
    },
    /// `[D(l)=]TRANS/...`: move the origin.
    Trans {
        /// The new coordinate system's label, when assigned.
        label: Option<Label>,
        /// Each origin moved and what it moves to.
        items: Vec<(Origin, TransBy)>,
    },
    /// `[D(l)=]ROTATE/axis,by`: rotate the coordinate system.
    Rotate {
        /// The new coordinate system's label, when assigned.
        label: Option<Label>,
        /// The axis rotated about.
        axis: RotAxis,
        /// An angle or a feature's direction.
        by: RotateBy,
    },
    /// `SAVE/D(l)`: keep the current coordinate system.
    Save(Label),
    /// `RECALL/D(l)`: make a saved coordinate system current.
    Recall(Label),
    /// `T(l)=TOL/...`: a tolerance.
    Tol {
        /// The tolerance's label.
        label: Label,
        /// The tolerance.
        tol: Tol,
    },
    /// `OUTPUT/FA(l),TA(l),...`: report actual features and tolerances.
    Output(Vec<Label>),
    /// `TEXT/kind,'text'`.
    Text {
        /// Where the text goes.
        kind: TextKind,
        /// The text.
        text: String,
    },
    /// `DID(l)=DEVICE/kind,'file'`: an output device.
    Device {
        /// The device's label.
        label: Label,
        /// What the device is.
        kind: DeviceKind,
        /// The file name, for a storage device.
        file: Option<String>,
    },
    /// `OPEN/DID(x),DIRECT,OUTPUT[,OVERWR|APPEND]`.
    Open {
        /// The device opened.
        device: Label,
        /// The words after the device (`DIRECT`, `OUTPUT`, `OVERWR`, ...).
        words: Vec<String>,
    },
    /// `CLOSE/DID(x)[,KEEP|DELETE]`.
    Close {
        /// The device closed.
        device: Label,
        /// `KEEP` or `DELETE`, when given.
        word: Option<String>,
    },
}

/// One item of `DISPLY`.
#[derive(Debug, Clone, PartialEq)]
pub enum DisplyItem {
    /// A word (`OFF`, `TERM`, `DMIS`, ...).
    Word(String),
    /// A device label.
    Device(Label),
}

impl Statement {
    /// The major word.
    pub fn major(&self) -> &'static str {
        match self {
            Statement::Dmismn { .. } => "DMISMN",
            Statement::Dmismd { .. } => "DMISMD",
            Statement::Endfil => "ENDFIL",
            Statement::Filnam { .. } => "FILNAM",
            Statement::Units { .. } => "UNITS",
            Statement::Disply(_) => "DISPLY",
            Statement::Prcomp(_) => "PRCOMP",
            Statement::Mode(_) => "MODE",
            Statement::Fedrat { .. } => "FEDRAT",
            Statement::Snset(_) => "SNSET",
            Statement::Snsdef { .. } => "SNSDEF",
            Statement::Snslct(_) => "SNSLCT",
            Statement::Snsmnt { .. } => "SNSMNT",
            Statement::Goto(_) => "GOTO",
            Statement::Feat { .. } => "FEAT",
            Statement::Meas { .. } => "MEAS",
            Statement::Endmes => "ENDMES",
            Statement::Ptmeas { .. } => "PTMEAS",
            Statement::Const { .. } => "CONST",
            Statement::Datdef { .. } => "DATDEF",
            Statement::Datset { .. } => "DATSET",
            Statement::Trans { .. } => "TRANS",
            Statement::Rotate { .. } => "ROTATE",
            Statement::Save(_) => "SAVE",
            Statement::Recall(_) => "RECALL",
            Statement::Tol { .. } => "TOL",
            Statement::Output(_) => "OUTPUT",
            Statement::Text { .. } => "TEXT",
            Statement::Device { .. } => "DEVICE",
            Statement::Open { .. } => "OPEN",
            Statement::Close { .. } => "CLOSE",
        }
    }
}

/// A number in its shortest exact form (`50`, `0.5`, `-1`, `1e-7` as `0.0000001`).
pub fn num(v: f64) -> String {
    format!("{v}")
}

fn push_nums(s: &mut String, v: &[f64]) {
    for x in v {
        s.push(',');
        s.push_str(&num(*x));
    }
}

fn text(t: &str) -> String {
    format!("'{}'", t.replace('\'', "''"))
}

impl Display for Statement {
    fn fmt(&self, f: &mut Formatter<'_>) -> fmt::Result {
        let mut s = String::new();
        match self {
            Statement::Dmismn { title, version }
            | Statement::Dmismd { title, version }
            | Statement::Filnam { name: title, version } => {
                write!(s, "{}/{}", self.major(), text(title))?;
                if let Some(v) = version {
                    push_nums(&mut s, &[*v]);
                }
            }
            Statement::Endfil | Statement::Endmes => s.push_str(self.major()),
            Statement::Units { length, angle, temp } => {
                write!(s, "UNITS/{length},{angle}")?;
                if let Some(t) = temp {
                    write!(s, ",{t}")?;
                }
            }
            Statement::Disply(items) => print_disply(&mut s, items)?,
            Statement::Prcomp(on) => write!(s, "PRCOMP/{}", if *on { "ON" } else { "OFF" })?,
            Statement::Mode(w) => {
                s.push_str("MODE/");
                s.push_str(&w.iter().map(|w| w.word()).collect::<Vec<_>>().join(","));
            }
            Statement::Fedrat { kind, unit, value } => {
                write!(s, "FEDRAT/{kind},{unit}")?;
                if let Some(v) = value {
                    push_nums(&mut s, &[*v]);
                }
            }
            Statement::Snset(it) => print_snset(&mut s, it)?,
            Statement::Snsdef { label, offset, dir, diam } => {
                write!(s, "{label}=SNSDEF/PROBE,FIXED,CART")?;
                push_nums(&mut s, offset);
                push_nums(&mut s, dir);
                push_nums(&mut s, &[*diam]);
            }
            Statement::Snslct(l) => write!(s, "SNSLCT/{l}")?,
            Statement::Snsmnt { xvec, zvec, mntlen } => print_snsmnt(&mut s, xvec, zvec, mntlen),
            Statement::Goto(g) => print_goto(&mut s, g)?,
            Statement::Feat { label, geom } => {
                write!(s, "{label}=FEAT/{}", geom.feat_type())?;
                print_feat_geom(&mut s, geom)?;
            }
            Statement::Meas { ftype, feature, n } => write!(s, "MEAS/{ftype},{feature},{n}")?,
            Statement::Ptmeas { p, n } => {
                s.push_str("PTMEAS/CART");
                push_nums(&mut s, p);
                if let Some(n) = n {
                    push_nums(&mut s, n);
                }
            }
            Statement::Const { ftype, feature, method } => {
                write!(s, "CONST/{ftype},{feature},")?;
                print_const_method(&mut s, method)?;
            }
            Statement::Datdef { datum, feature, assigned } => {
                if *assigned {
                    write!(s, "{datum}=DATDEF/{feature}")?;
                } else {
                    write!(s, "DATDEF/{feature},{datum}")?;
                }
            }
            Statement::Datset { label, def } => {
                write!(s, "{label}=DATSET/")?;
                print_datset(&mut s, def)?;
            }
            Statement::Trans { label, items } => print_trans(&mut s, label, items)?,
            Statement::Rotate { label, axis, by } => print_rotate(&mut s, label, *axis, by)?,
            Statement::Save(l) => write!(s, "SAVE/{l}")?,
            Statement::Recall(l) => write!(s, "RECALL/{l}")?,
            Statement::Tol { label, tol } => {
                write!(s, "{label}=TOL/{}", tol.word())?;
                print_tol(&mut s, tol)?;
            }
            Statement::Output(ls) => {
                s.push_str("OUTPUT/");
                s.push_str(&ls.iter().map(|l| l.to_string()).collect::<Vec<_>>().join(","));
            }
            Statement::Text { kind, text: t } => write!(s, "TEXT/{kind},{}", text(t))?,
            Statement::Device { label, kind, file } => {
                write!(s, "{label}=DEVICE/{kind}")?;
                if let Some(fl) = file {
                    write!(s, ",{}", text(fl))?;
                }
            }
            Statement::Open { device, words } => print_device_words(&mut s, "OPEN", device, words)?,
            Statement::Close { device, word } => print_device_words(&mut s, "CLOSE", device, word)?,
        }
        f.write_str(&s)
    }
}

/// `DISPLY/` and its words and device labels.
fn print_disply(s: &mut String, items: &[DisplyItem]) -> fmt::Result {
    s.push_str("DISPLY/");
    for (k, it) in items.iter().enumerate() {
        if k > 0 {
            s.push(',');
        }
        match it {
            DisplyItem::Word(w) => s.push_str(w),
            DisplyItem::Device(l) => write!(s, "{l}")?,
        }
    }
    Ok(())
}

/// `SNSET/` and its item.
fn print_snset(s: &mut String, it: &Snset) -> fmt::Result {
    s.push_str("SNSET/");
    match it {
        Snset::Apprch(v) => write!(s, "APPRCH,{}", num(*v))?,
        Snset::Retrct(v) => write!(s, "RETRCT,{}", num(*v))?,
        Snset::Search(v) => write!(s, "SEARCH,{}", num(*v))?,
        Snset::Depth(v) => write!(s, "DEPTH,{}", num(*v))?,
        Snset::Clrsrf(None, v) => write!(s, "CLRSRF,{}", num(*v))?,
        Snset::Clrsrf(Some(l), v) => write!(s, "CLRSRF,{l},{}", num(*v))?,
        Snset::ClrsrfOff => s.push_str("CLRSRF,OFF"),
    }
    Ok(())
}

/// `SNSMNT/` with its three vectors.
fn print_snsmnt(s: &mut String, xvec: &Xyz, zvec: &Xyz, mntlen: &Xyz) {
    s.push_str("SNSMNT/XVEC");
    push_nums(s, xvec);
    s.push_str(",ZVEC");
    push_nums(s, zvec);
    s.push_str(",MNTLEN");
    push_nums(s, mntlen);
}

/// `GOTO/` to a point or by a distance along a direction.
fn print_goto(s: &mut String, g: &Goto) -> fmt::Result {
    match g {
        Goto::Abs(p) => {
            s.push_str("GOTO/");
            s.push_str(&p.iter().map(|v| num(*v)).collect::<Vec<_>>().join(","));
        }
        Goto::Incr { dist, dir } => {
            write!(s, "GOTO/INCR,{}", num(*dist))?;
            push_nums(s, dir);
        }
    }
    Ok(())
}

/// The arguments of `FEAT/type` after the type: side, `CART` and the numbers.
fn print_feat_geom(s: &mut String, geom: &FeatGeom) -> fmt::Result {
    match geom {
        FeatGeom::Point { p, n } | FeatGeom::Plane { p, n } => {
            s.push_str(",CART");
            push_nums(s, p);
            push_nums(s, n);
        }
        FeatGeom::LineUnbnd { p, dir, plane } => {
            s.push_str(",UNBND,CART");
            push_nums(s, p);
            push_nums(s, dir);
            if let Some(pl) = plane {
                push_nums(s, pl);
            }
        }
        FeatGeom::LineBnd { p1, p2, plane } => {
            s.push_str(",BND,CART");
            push_nums(s, p1);
            push_nums(s, p2);
            if let Some(pl) = plane {
                push_nums(s, pl);
            }
        }
        FeatGeom::Circle { side, c, n, diam } => {
            write!(s, ",{side},CART")?;
            push_nums(s, c);
            push_nums(s, n);
            push_nums(s, &[*diam]);
        }
        FeatGeom::Cylndr { side, p, axis, diam, length } => {
            write!(s, ",{side},CART")?;
            push_nums(s, p);
            push_nums(s, axis);
            push_nums(s, &[*diam]);
            if let Some(l) = length {
                push_nums(s, &[*l]);
            }
        }
        FeatGeom::Sphere { side, c, n, diam } => {
            write!(s, ",{side},CART")?;
            push_nums(s, c);
            if let Some(n) = n {
                push_nums(s, n);
            }
            push_nums(s, &[*diam]);
        }
        FeatGeom::Cone { side, apex, axis, angle } => {
            write!(s, ",{side},CART")?;
            push_nums(s, apex);
            push_nums(s, axis);
            push_nums(s, &[*angle]);
        }
    }
    Ok(())
}

/// The method of `CONST` and the features it takes.
fn print_const_method(s: &mut String, method: &ConstMethod) -> fmt::Result {
    match method {
        ConstMethod::Bf(ls) => {
            s.push_str("BF");
            for l in ls {
                write!(s, ",{l}")?;
            }
        }
        ConstMethod::Intof(a, b) => write!(s, "INTOF,{a},{b}")?,
        ConstMethod::Projct(a, b) => write!(s, "PROJCT,{a},{b}")?,
        ConstMethod::Midpt(a, b) => write!(s, "MIDPT,{a},{b}")?,
    }
    Ok(())
}

/// The arguments of `DATSET/`: `MCS`, or each datum with its axis and origin words.
fn print_datset(s: &mut String, def: &Datset) -> fmt::Result {
    match def {
        Datset::Mcs => s.push_str("MCS"),
        Datset::Datums(ds) => {
            let mut first = true;
            for (l, ws) in ds {
                if !first {
                    s.push(',');
                }
                first = false;
                write!(s, "{l}")?;
                for w in ws {
                    write!(s, ",{w}")?;
                }
            }
        }
    }
    Ok(())
}

/// `[D(l)=]TRANS/` and each origin with its value or feature.
fn print_trans(s: &mut String, label: &Option<Label>, items: &[(Origin, TransBy)]) -> fmt::Result {
    if let Some(l) = label {
        write!(s, "{l}=")?;
    }
    s.push_str("TRANS/");
    for (k, (o, by)) in items.iter().enumerate() {
        if k > 0 {
            s.push(',');
        }
        match by {
            TransBy::Value(v) => write!(s, "{o},{}", num(*v))?,
            TransBy::Feature(l) => write!(s, "{o},{l}")?,
        }
    }
    Ok(())
}

/// `[D(l)=]ROTATE/` about an axis by an angle or to a feature's direction.
fn print_rotate(s: &mut String, label: &Option<Label>, axis: RotAxis, by: &RotateBy) -> fmt::Result {
    if let Some(l) = label {
        write!(s, "{l}=")?;
    }
    write!(s, "ROTATE/{axis},")?;
    match by {
        RotateBy::Angle(a) => s.push_str(&num(*a)),
        RotateBy::Feature(l, d) => write!(s, "{l},{d}")?,
    }
    Ok(())
}

/// `OPEN/` or `CLOSE/` of a device and the words after it.
fn print_device_words<'a>(
    s: &mut String,
    major: &str,
    device: &Label,
    words: impl IntoIterator<Item = &'a String>,
) -> fmt::Result {
    write!(s, "{major}/{device}")?;
    for w in words {
        write!(s, ",{w}")?;
    }
    Ok(())
}

/// The arguments of `TOL/kind` after the kind.
fn print_tol(s: &mut String, tol: &Tol) -> fmt::Result {
    match tol {
        Tol::Flat(v) | Tol::Strght(v) | Tol::Cirlty(v) | Tol::Cylcty(v) => push_nums(s, &[*v]),
        Tol::Diam { lo, hi } | Tol::Rad { lo, hi } => push_nums(s, &[*lo, *hi]),
        Tol::Pos { three_d, zone, cond, datums } => {
            s.push_str(if *three_d { ",3D" } else { ",2D" });
            push_nums(s, &[*zone]);
            write!(s, ",{cond}")?;
            for d in datums {
                write!(s, ",{d}")?;
            }
        }
        Tol::Perp { zone, datum } | Tol::Parlel { zone, datum } => {
            push_nums(s, &[*zone]);
            write!(s, ",{datum}")?;
        }
        Tol::Anglb { angle, lo, hi } => push_nums(s, &[*angle, *lo, *hi]),
        Tol::Distb { dist, lo, hi, axis } => {
            s.push_str(",NOMINL");
            push_nums(s, &[*dist, *lo, *hi]);
            if let Some(a) = axis {
                write!(s, ",{a}")?;
            }
        }
    }
    Ok(())
}
