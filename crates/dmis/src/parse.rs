//! The parser: tokens of one statement ([`crate::lexer::RawStatement`]) → a typed
//! [`Statement`] with the positions of its parts ([`Stmt`]), and whole programs ([`parse`]).
//!
//! A statement is `[label =] MAJOR[/arg{,arg}]`; each argument is one word, number, text or
//! label. Words outside the subset are refused as [`ErrorKind::Unsupported`] at their place;
//! anything that is not DMIS as [`ErrorKind::Syntax`].

use crate::ast::*;
use crate::error::{DmisError, ErrorKind, Pos};
use crate::lexer::{statements, RawStatement, Tok};

/// A statement with where it is: its first character and each argument's.
#[derive(Debug, Clone, PartialEq)]
pub struct Stmt {
    /// The parsed statement.
    pub statement: Statement,
    /// Its first character.
    pub pos: Pos,
    /// Position of the label before `=` (or of the statement).
    pub label_pos: Pos,
    /// Position of each argument after `/`, in order.
    pub args: Vec<Pos>,
}

impl Stmt {
    /// The position of argument `k` (the statement's when there is none).
    pub fn arg(&self, k: usize) -> Pos {
        self.args.get(k).copied().unwrap_or(self.pos)
    }
}

/// A parsed program.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    /// The file name errors are reported with.
    pub file: String,
    /// The statements, in order.
    pub statements: Vec<Stmt>,
}

impl Program {
    /// The program in canonical DMIS, one statement a line.
    pub fn print(&self) -> String {
        let mut s = String::new();
        for st in &self.statements {
            s.push_str(&st.statement.to_string());
            s.push('\n');
        }
        s
    }
    /// Just the statements (what a round trip preserves).
    pub fn statements(&self) -> Vec<&Statement> {
        self.statements.iter().map(|s| &s.statement).collect()
    }
}

/// Parse a whole program; the first error is returned (file, line, column).
pub fn parse(file: &str, text: &str) -> Result<Program, DmisError> {
    let mut out = Vec::with_capacity(text.len() / 32);
    for raw in statements(file, text) {
        out.push(parse_statement(file, &raw?)?);
    }
    Ok(Program { file: file.to_string(), statements: out })
}

struct Cursor<'a> {
    file: &'a str,
    major: &'a str,
    args: Vec<(&'a Tok, Pos)>,
    k: usize,
    end: Pos,
}

impl<'a> Cursor<'a> {
    fn err(&self, pos: Pos, kind: ErrorKind, m: impl Into<String>) -> DmisError {
        DmisError::new(self.file, pos, kind, m)
    }
    fn here(&self) -> Pos {
        self.args.get(self.k).map(|a| a.1).unwrap_or(self.end)
    }
    fn peek(&self) -> Option<&'a Tok> {
        self.args.get(self.k).map(|a| a.0)
    }
    fn missing(&self, what: &str) -> DmisError {
        match self.args.get(self.k) {
            None => self.err(
                self.end,
                ErrorKind::Syntax,
                format!("{}: {what} expected at the end of the statement", self.major),
            ),
            Some((t, p)) => self.err(
                *p,
                ErrorKind::Syntax,
                format!("{}: {what} expected, found {}", self.major, t.describe()),
            ),
        }
    }
    fn num(&mut self, what: &str) -> Result<f64, DmisError> {
        match self.peek() {
            Some(Tok::Num(v)) => {
                self.k += 1;
                Ok(*v)
            }
            _ => Err(self.missing(&format!("a number ({what})"))),
        }
    }
    fn xyz(&mut self, what: &str) -> Result<Xyz, DmisError> {
        Ok([
            self.num(&format!("{what}, first of three"))?,
            self.num(&format!("{what}, second of three"))?,
            self.num(&format!("{what}, third of three"))?,
        ])
    }
    fn has_num(&self) -> bool {
        matches!(self.peek(), Some(Tok::Num(_)))
    }
    fn count_nums(&self) -> usize {
        self.args[self.k..].iter().take_while(|a| matches!(a.0, Tok::Num(_))).count()
    }
    fn text(&mut self, what: &str) -> Result<String, DmisError> {
        match self.peek() {
            Some(Tok::Text(s)) => {
                self.k += 1;
                Ok(s.clone())
            }
            _ => Err(self.missing(&format!("a text in apostrophes ({what})"))),
        }
    }
    /// A word of the given kind; a word outside it is Unsupported if `known` says DMIS has it.
    fn word_of<T: Copy>(
        &mut self,
        what: &str,
        from: impl Fn(&str) -> Option<T>,
        all: &[&str],
    ) -> Result<T, DmisError> {
        match self.peek() {
            Some(Tok::Word(w)) => match from(w) {
                Some(v) => {
                    self.k += 1;
                    Ok(v)
                }
                None => Err(self.err(
                    self.here(),
                    ErrorKind::Unsupported,
                    format!("{}: {w} is not supported as {what} (supported: {})", self.major, all.join(", ")),
                )),
            },
            _ => Err(self.missing(&format!("{what} ({})", all.join(", ")))),
        }
    }
    fn keyword(&mut self, w: &str) -> Result<(), DmisError> {
        match self.peek() {
            Some(Tok::Word(x)) if x == w => {
                self.k += 1;
                Ok(())
            }
            Some(Tok::Word(x)) => Err(self.err(
                self.here(),
                ErrorKind::Unsupported,
                format!("{}: {x} is not supported here (supported: {w})", self.major),
            )),
            _ => Err(self.missing(w)),
        }
    }
    fn is_word(&self, w: &str) -> bool {
        matches!(self.peek(), Some(Tok::Word(x)) if x == w)
    }
    fn any_word(&mut self, what: &str) -> Result<String, DmisError> {
        match self.peek() {
            Some(Tok::Word(w)) => {
                self.k += 1;
                Ok(w.clone())
            }
            _ => Err(self.missing(what)),
        }
    }
    fn label(&mut self, kinds: &[LabelKind], what: &str) -> Result<Label, DmisError> {
        let names = kinds.iter().map(|k| format!("{}()", k.prefix())).collect::<Vec<_>>().join(" or ");
        match self.peek() {
            Some(Tok::Label(p, n)) => match LabelKind::from_prefix(p) {
                Some(k) if kinds.contains(&k) => {
                    self.k += 1;
                    Ok(Label { kind: k, name: n.clone() })
                }
                _ => Err(self.err(
                    self.here(),
                    ErrorKind::Syntax,
                    format!("{}: {what} must be a {names} label, found {p}({n})", self.major),
                )),
            },
            _ => Err(self.missing(&format!("{what} ({names})"))),
        }
    }
    fn is_label(&self) -> bool {
        matches!(self.peek(), Some(Tok::Label(..)))
    }
    fn side(&mut self) -> Result<Side, DmisError> {
        let all: Vec<&str> = Side::ALL.iter().map(|w| w.word()).collect();
        self.word_of("the side", Side::from_word, &all)
    }
    fn done(&self) -> Result<(), DmisError> {
        match self.args.get(self.k) {
            None => Ok(()),
            Some((t, p)) => Err(self.err(
                *p,
                ErrorKind::Syntax,
                format!("{}: unexpected {} (too many arguments)", self.major, t.describe()),
            )),
        }
    }
}

fn words_of<T: Copy>(all: &[T], f: impl Fn(T) -> &'static str) -> Vec<&'static str> {
    all.iter().map(|w| f(*w)).collect()
}

/// Majors of DMIS outside the subset: refused as Unsupported rather than "unknown".
const OTHER_MAJORS: &[&str] = &[
    "ACLRAT",
    "ALGDEF",
    "ASSIGN",
    "BADTST",
    "BOUND",
    "CALIB",
    "CALL",
    "CASE",
    "CLMPID",
    "CLMPSN",
    "CRGDEF",
    "CRMODE",
    "CROSCL",
    "CRSLCT",
    "CUTCOM",
    "CZONE",
    "CZSLCT",
    "DECL",
    "DECPL",
    "DEFALT",
    "DMEHW",
    "DMESW",
    "DMESWI",
    "DMESWV",
    "DO",
    "ELSE",
    "ENDAXS",
    "ENDCAS",
    "ENDDO",
    "ENDGO",
    "ENDIF",
    "ENDMAC",
    "ENDSEL",
    "ENDSIM",
    "ENDX",
    "EQUATE",
    "ERROR",
    "EVAL",
    "EXTENS",
    "EXTFIL",
    "FILDEF",
    "FINPOS",
    "FIXTID",
    "FIXTSN",
    "FROM",
    "GECOMP",
    "GEOALG",
    "GEOM",
    "GOHOME",
    "GOTARG",
    "GROUP",
    "IF",
    "INCLUD",
    "ITERAT",
    "JUMPTO",
    "KEYCHAR",
    "LITDEF",
    "LOCATE",
    "LOTID",
    "MACRO",
    "MFGDEV",
    "OBTAIN",
    "OPERID",
    "PAMEAS",
    "PARTID",
    "PARTRV",
    "PARTSN",
    "PLANID",
    "POP",
    "PREVOP",
    "PROCID",
    "PUSH",
    "QISDEF",
    "RAPID",
    "READ",
    "REPORT",
    "RESUME",
    "RMEAS",
    "ROTAB",
    "ROTDEF",
    "ROTSET",
    "SCNMOD",
    "SCNSET",
    "SELECT",
    "SENSOR",
    "SNSGRP",
    "TECOMP",
    "THLDEF",
    "TOOLDF",
    "UNCERTALG",
    "UNCERTSET",
    "VALUE",
    "VFORM",
    "WINDEF",
    "WKPLAN",
    "WRIST",
    "WRITE",
    "XTERN",
    "XTRACT",
];

/// A statement split into its label, major word (and its position), argument token indices and
/// whether it has a `/`.
type Split = (Option<(Label, Pos)>, String, Pos, Vec<(usize, Pos)>, bool);

fn split(file: &str, raw: &RawStatement) -> Result<Split, DmisError> {
    let toks = &raw.toks;
    let syn = |p: Pos, m: String| DmisError::new(file, p, ErrorKind::Syntax, m);
    let mut k = 0;
    let mut label = None;
    if toks.len() >= 2 && toks[1].0 == Tok::Eq {
        match &toks[0].0 {
            Tok::Label(p, n) => match LabelKind::from_prefix(p) {
                Some(kind) => label = Some((Label { kind, name: n.clone() }, toks[0].1)),
                None => {
                    return Err(DmisError::new(
                        file,
                        toks[0].1,
                        ErrorKind::Unsupported,
                        format!(
                        "labels {p}() are not supported (supported: F, FA, D, DA, DAT, T, TA, S, SA, DID)"
                    ),
                    ))
                }
            },
            t => return Err(syn(toks[0].1, format!("a label expected before '=', found {}", t.describe()))),
        }
        k = 2;
    }
    let (major, mpos) = match toks.get(k) {
        Some((Tok::Word(w), p)) => (w.clone(), *p),
        Some((t, p)) => {
            return Err(syn(
                *p,
                format!("a statement must start with its major word, found {}", t.describe()),
            ))
        }
        None => return Err(syn(raw.end, "a statement expected after '='".into())),
    };
    k += 1;
    let mut args = Vec::new();
    let mut slash = false;
    if k < toks.len() {
        if toks[k].0 != Tok::Slash {
            return Err(syn(
                toks[k].1,
                format!("{major}: '/' expected after the major word, found {}", toks[k].0.describe()),
            ));
        }
        slash = true;
        k += 1;
        loop {
            match toks.get(k) {
                None => break,
                Some((Tok::Comma, p)) | Some((Tok::Slash, p)) | Some((Tok::Eq, p)) => {
                    return Err(syn(
                        *p,
                        format!("{major}: an argument expected, found {}", toks[k].0.describe()),
                    ))
                }
                Some((_, p)) => args.push((k, *p)),
            }
            k += 1;
            match toks.get(k) {
                None => break,
                Some((Tok::Comma, p)) => {
                    if k + 1 >= toks.len() {
                        return Err(syn(*p, format!("{major}: an argument expected after the last ','")));
                    }
                    k += 1;
                }
                Some((t, p)) => {
                    return Err(syn(
                        *p,
                        format!("{major}: ',' expected between arguments, found {}", t.describe()),
                    ))
                }
            }
        }
    }
    Ok((label, major, mpos, args, slash))
}

/// Parse one statement's tokens.
pub fn parse_statement(file: &str, raw: &RawStatement) -> Result<Stmt, DmisError> {
    let (label, major, mpos, arg_idx, _slash) = split(file, raw)?;
    let start = label.as_ref().map(|l| l.1).unwrap_or(mpos);
    let args: Vec<(&Tok, Pos)> = arg_idx.iter().map(|(k, p)| (&raw.toks[*k].0, *p)).collect();
    let arg_pos: Vec<Pos> = args.iter().map(|a| a.1).collect();
    let mut c = Cursor { file, major: &major, args, k: 0, end: raw.end };
    let need_label = |kinds: &[LabelKind]| -> Result<Label, DmisError> {
        let names = kinds.iter().map(|k| format!("{}()", k.prefix())).collect::<Vec<_>>().join(" or ");
        match &label {
            Some((l, p)) if kinds.contains(&l.kind) => {
                let _ = p;
                Ok(l.clone())
            }
            Some((l, p)) => Err(DmisError::new(
                file,
                *p,
                ErrorKind::Syntax,
                format!("{major} needs a {names} label, found {l}"),
            )),
            None => Err(DmisError::new(
                file,
                mpos,
                ErrorKind::Syntax,
                format!("{major} needs a label: {names} = {major}/…"),
            )),
        }
    };
    let no_label = || -> Result<(), DmisError> {
        match &label {
            Some((l, p)) => {
                Err(DmisError::new(file, *p, ErrorKind::Syntax, format!("{major} takes no label ({l} =)")))
            }
            None => Ok(()),
        }
    };
    let opt_label = |kinds: &[LabelKind]| -> Result<Option<Label>, DmisError> {
        match &label {
            None => Ok(None),
            Some(_) => need_label(kinds).map(Some),
        }
    };
    use LabelKind as L;
    let st = match major.as_str() {
        "DMISMN" | "DMISMD" | "FILNAM" => {
            no_label()?;
            let title = c.text("the name")?;
            let version = if c.has_num() { Some(c.num("the DMIS version")?) } else { None };
            match major.as_str() {
                "DMISMN" => Statement::Dmismn { title, version },
                "DMISMD" => Statement::Dmismd { title, version },
                _ => Statement::Filnam { name: title, version },
            }
        }
        "ENDFIL" => {
            no_label()?;
            Statement::Endfil
        }
        "ENDMES" => {
            no_label()?;
            Statement::Endmes
        }
        "UNITS" => {
            no_label()?;
            let length = c.word_of(
                "the length unit",
                LengthUnit::from_word,
                &words_of(LengthUnit::ALL, LengthUnit::word),
            )?;
            let angle = c.word_of(
                "the angle unit",
                AngleUnit::from_word,
                &words_of(AngleUnit::ALL, AngleUnit::word),
            )?;
            let temp = if c.peek().is_some() {
                Some(c.word_of(
                    "the temperature unit",
                    TempUnit::from_word,
                    &words_of(TempUnit::ALL, TempUnit::word),
                )?)
            } else {
                None
            };
            Statement::Units { length, angle, temp }
        }
        "DISPLY" => {
            no_label()?;
            let mut items = Vec::new();
            while c.peek().is_some() {
                if c.is_label() {
                    items.push(DisplyItem::Device(c.label(&[L::Did], "the display device")?));
                } else {
                    let w = c.any_word("OFF, TERM, STOR, PRINT, DMIS, V or a DID() label")?;
                    if !matches!(w.as_str(), "OFF" | "TERM" | "STOR" | "PRINT" | "COMM" | "DMIS" | "V") {
                        return Err(c.err(
                            c.args[c.k - 1].1,
                            ErrorKind::Unsupported,
                            format!("DISPLY: {w} is not supported (OFF, TERM, STOR, PRINT, COMM, DMIS, V)"),
                        ));
                    }
                    items.push(DisplyItem::Word(w));
                }
            }
            if items.is_empty() {
                return Err(c.missing("OFF or a display device"));
            }
            Statement::Disply(items)
        }
        "PRCOMP" => {
            no_label()?;
            let on = c.word_of(
                "the switch",
                |w| match w {
                    "ON" => Some(true),
                    "OFF" => Some(false),
                    _ => None,
                },
                &["ON", "OFF"],
            )?;
            Statement::Prcomp(on)
        }
        "MODE" => {
            no_label()?;
            let mut w =
                vec![c.word_of("the mode", ModeWord::from_word, &words_of(ModeWord::ALL, ModeWord::word))?];
            while c.peek().is_some() {
                w.push(c.word_of(
                    "the mode",
                    ModeWord::from_word,
                    &words_of(ModeWord::ALL, ModeWord::word),
                )?);
            }
            Statement::Mode(w)
        }
        "FEDRAT" => {
            no_label()?;
            let kind =
                c.word_of("the speed", FeedKind::from_word, &words_of(FeedKind::ALL, FeedKind::word))?;
            let unit =
                c.word_of("the unit", FeedUnit::from_word, &words_of(FeedUnit::ALL, FeedUnit::word))?;
            let value = match unit {
                FeedUnit::High | FeedUnit::Low | FeedUnit::Defalt => None,
                _ => Some(c.num("the speed")?),
            };
            Statement::Fedrat { kind, unit, value }
        }
        "SNSET" => {
            no_label()?;
            let w = c.any_word("APPRCH, RETRCT, SEARCH, DEPTH or CLRSRF")?;
            let it = match w.as_str() {
                "APPRCH" => Snset::Apprch(c.num("the approach distance")?),
                "RETRCT" => Snset::Retrct(c.num("the retract distance")?),
                "SEARCH" => Snset::Search(c.num("the search distance")?),
                "DEPTH" => Snset::Depth(c.num("the depth")?),
                "CLRSRF" => {
                    if c.is_word("OFF") {
                        c.k += 1;
                        Snset::ClrsrfOff
                    } else {
                        let f = if c.is_label() {
                            Some(c.label(&[L::F, L::Fa], "the clearance plane")?)
                        } else {
                            None
                        };
                        Snset::Clrsrf(f, c.num("the clearance distance")?)
                    }
                }
                other => {
                    return Err(c.err(
                        c.args[0].1,
                        ErrorKind::Unsupported,
                        format!("SNSET/{other} is not supported (APPRCH, RETRCT, SEARCH, DEPTH, CLRSRF)"),
                    ))
                }
            };
            Statement::Snset(it)
        }
        "SNSDEF" => {
            let label = need_label(&[L::S])?;
            c.keyword("PROBE")?;
            c.keyword("FIXED")?;
            c.keyword("CART")?;
            let offset = c.xyz("the probe offset")?;
            let dir = c.xyz("the probe direction")?;
            let diam = c.num("the tip diameter")?;
            Statement::Snsdef { label, offset, dir, diam }
        }
        "SNSLCT" => {
            no_label()?;
            Statement::Snslct(c.label(&[L::S, L::Sa], "the sensor")?)
        }
        "SNSMNT" => {
            no_label()?;
            c.keyword("XVEC")?;
            let xvec = c.xyz("XVEC")?;
            c.keyword("ZVEC")?;
            let zvec = c.xyz("ZVEC")?;
            c.keyword("MNTLEN")?;
            let mntlen = c.xyz("MNTLEN")?;
            Statement::Snsmnt { xvec, zvec, mntlen }
        }
        "GOTO" => {
            no_label()?;
            if c.is_word("INCR") {
                c.k += 1;
                let dist = c.num("the distance")?;
                Statement::Goto(Goto::Incr { dist, dir: c.xyz("the direction")? })
            } else {
                if c.is_word("CART") {
                    c.k += 1;
                }
                Statement::Goto(Goto::Abs(c.xyz("the target")?))
            }
        }
        "FEAT" => {
            let label = need_label(&[L::F, L::Fa])?;
            let ft =
                c.word_of("the feature type", FeatType::from_word, &words_of(FeatType::ALL, FeatType::word))?;
            let geom = match ft {
                FeatType::Point | FeatType::Plane => {
                    c.keyword("CART")?;
                    let p = c.xyz("the point")?;
                    let n = c.xyz("the normal")?;
                    if ft == FeatType::Point {
                        FeatGeom::Point { p, n }
                    } else {
                        FeatGeom::Plane { p, n }
                    }
                }
                FeatType::Line => {
                    let bnd = c.word_of(
                        "UNBND or BND",
                        |w| match w {
                            "UNBND" => Some(false),
                            "BND" => Some(true),
                            _ => None,
                        },
                        &["UNBND", "BND"],
                    )?;
                    c.keyword("CART")?;
                    let a = c.xyz(if bnd { "the start point" } else { "the point" })?;
                    let b = c.xyz(if bnd { "the end point" } else { "the direction" })?;
                    let plane = if c.has_num() { Some(c.xyz("the plane normal")?) } else { None };
                    if bnd {
                        FeatGeom::LineBnd { p1: a, p2: b, plane }
                    } else {
                        FeatGeom::LineUnbnd { p: a, dir: b, plane }
                    }
                }
                FeatType::Circle => {
                    let side = c.side()?;
                    c.keyword("CART")?;
                    FeatGeom::Circle {
                        side,
                        c: c.xyz("the centre")?,
                        n: c.xyz("the normal")?,
                        diam: c.num("the diameter")?,
                    }
                }
                FeatType::Cylndr => {
                    let side = c.side()?;
                    c.keyword("CART")?;
                    let p = c.xyz("the axis point")?;
                    let axis = c.xyz("the axis")?;
                    let diam = c.num("the diameter")?;
                    let length = if c.has_num() { Some(c.num("the length")?) } else { None };
                    FeatGeom::Cylndr { side, p, axis, diam, length }
                }
                FeatType::Sphere => {
                    let side = c.side()?;
                    c.keyword("CART")?;
                    let cc = c.xyz("the centre")?;
                    let n = if c.count_nums() >= 4 { Some(c.xyz("the direction")?) } else { None };
                    FeatGeom::Sphere { side, c: cc, n, diam: c.num("the diameter")? }
                }
                FeatType::Cone => {
                    let side = c.side()?;
                    c.keyword("CART")?;
                    FeatGeom::Cone {
                        side,
                        apex: c.xyz("the apex")?,
                        axis: c.xyz("the axis")?,
                        angle: c.num("the included angle")?,
                    }
                }
            };
            Statement::Feat { label, geom }
        }
        "MEAS" => {
            no_label()?;
            let ftype =
                c.word_of("the feature type", FeatType::from_word, &words_of(FeatType::ALL, FeatType::word))?;
            let feature = c.label(&[L::F], "the feature")?;
            let p = c.here();
            let n = c.num("the number of points")?;
            if !((1.0..=100_000.0).contains(&n) && n.fract() == 0.0) {
                return Err(c.err(
                    p,
                    ErrorKind::Syntax,
                    format!("MEAS: the number of points must be a whole number from 1 to 100000, not {n}"),
                ));
            }
            Statement::Meas { ftype, feature, n: n as u32 }
        }
        "PTMEAS" => {
            no_label()?;
            c.keyword("CART")?;
            let p = c.xyz("the point")?;
            let n = if c.has_num() { Some(c.xyz("the approach direction")?) } else { None };
            Statement::Ptmeas { p, n }
        }
        "CONST" => {
            no_label()?;
            let ftype =
                c.word_of("the feature type", FeatType::from_word, &words_of(FeatType::ALL, FeatType::word))?;
            let feature = c.label(&[L::F], "the constructed feature")?;
            let m = c.any_word("BF, INTOF, PROJCT or MIDPT")?;
            let src = &[L::Fa, L::F];
            let method = match m.as_str() {
                "BF" => {
                    let mut ls = vec![c.label(src, "a feature")?];
                    while c.peek().is_some() {
                        ls.push(c.label(src, "a feature")?);
                    }
                    ConstMethod::Bf(ls)
                }
                "INTOF" => ConstMethod::Intof(
                    c.label(src, "the first feature")?,
                    c.label(src, "the second feature")?,
                ),
                "PROJCT" => {
                    ConstMethod::Projct(c.label(src, "the feature to project")?, c.label(src, "the plane")?)
                }
                "MIDPT" => ConstMethod::Midpt(
                    c.label(src, "the first feature")?,
                    c.label(src, "the second feature")?,
                ),
                other => {
                    return Err(c.err(
                        c.args[2].1,
                        ErrorKind::Unsupported,
                        format!("CONST: {other} is not supported (BF, INTOF, PROJCT, MIDPT)"),
                    ))
                }
            };
            Statement::Const { ftype, feature, method }
        }
        "DATDEF" => {
            if label.is_some() {
                let datum = need_label(&[L::Dat, L::Da])?;
                Statement::Datdef {
                    datum,
                    feature: c.label(&[L::Fa, L::F], "the datum feature")?,
                    assigned: true,
                }
            } else {
                let feature = c.label(&[L::Fa, L::F], "the datum feature")?;
                Statement::Datdef { feature, datum: c.label(&[L::Dat, L::Da], "the datum")?, assigned: false }
            }
        }
        "DATSET" => {
            let l = need_label(&[L::D])?;
            if c.is_word("MCS") {
                c.k += 1;
                Statement::Datset { label: l, def: Datset::Mcs }
            } else {
                let mut ds = Vec::new();
                while c.peek().is_some() {
                    let d = c.label(&[L::Dat, L::Da, L::Fa], "a datum")?;
                    let mut ws = Vec::new();
                    while matches!(c.peek(), Some(Tok::Word(_))) {
                        ws.push(c.word_of(
                            "an axis or origin",
                            DatsetWord::from_word,
                            &words_of(DatsetWord::ALL, DatsetWord::word),
                        )?);
                    }
                    if ws.is_empty() {
                        return Err(c.missing("an axis or origin (XDIR, YDIR, ZDIR, XORIG, YORIG, ZORIG)"));
                    }
                    ds.push((d, ws));
                }
                if ds.is_empty() {
                    return Err(c.missing("MCS or datums"));
                }
                Statement::Datset { label: l, def: Datset::Datums(ds) }
            }
        }
        "TRANS" => {
            let l = opt_label(&[L::D])?;
            let mut items = Vec::new();
            loop {
                let o = c.word_of("the origin", Origin::from_word, &words_of(Origin::ALL, Origin::word))?;
                let by = if c.is_label() {
                    TransBy::Feature(c.label(&[L::Fa, L::F], "the feature")?)
                } else {
                    TransBy::Value(c.num("the new origin")?)
                };
                items.push((o, by));
                if c.peek().is_none() {
                    break;
                }
            }
            Statement::Trans { label: l, items }
        }
        "ROTATE" => {
            let l = opt_label(&[L::D])?;
            let axis = c.word_of("the axis", RotAxis::from_word, &words_of(RotAxis::ALL, RotAxis::word))?;
            let by = if c.is_label() {
                let f = c.label(&[L::Fa, L::F], "the feature")?;
                RotateBy::Feature(
                    f,
                    c.word_of("the direction", AxisDir::from_word, &words_of(AxisDir::ALL, AxisDir::word))?,
                )
            } else {
                RotateBy::Angle(c.num("the angle")?)
            };
            Statement::Rotate { label: l, axis, by }
        }
        "SAVE" | "RECALL" => {
            no_label()?;
            let l = c.label(&[L::D, L::Da], "the coordinate system")?;
            if major == "SAVE" {
                Statement::Save(l)
            } else {
                Statement::Recall(l)
            }
        }
        "TOL" => {
            let l = need_label(&[L::T])?;
            let w = c.any_word("the tolerance kind")?;
            let tol = match w.as_str() {
                "FLAT" => Tol::Flat(c.num("the zone")?),
                "STRGHT" => Tol::Strght(c.num("the zone")?),
                "CIRLTY" => Tol::Cirlty(c.num("the zone")?),
                "CYLCTY" => Tol::Cylcty(c.num("the zone")?),
                "DIAM" => Tol::Diam { lo: c.num("the lower deviation")?, hi: c.num("the upper deviation")? },
                "RAD" => Tol::Rad { lo: c.num("the lower deviation")?, hi: c.num("the upper deviation")? },
                "POS" => {
                    let three_d = c.word_of("2D or 3D", |w| match w {
                        "2D" => Some(false),
                        "3D" => Some(true),
                        _ => None,
                    }, &["2D", "3D"])?;
                    let zone = c.num("the zone diameter")?;
                    let cond = c.word_of("the material condition", MatCond::from_word, &words_of(MatCond::ALL, MatCond::word))?;
                    let mut datums = Vec::new();
                    while c.peek().is_some() {
                        datums.push(c.label(&[L::Dat, L::Da], "a datum")?);
                    }
                    Tol::Pos { three_d, zone, cond, datums }
                }
                "PERP" | "PARLEL" => {
                    let zone = c.num("the zone")?;
                    let datum = c.label(&[L::Dat, L::Da, L::Fa, L::F], "the datum")?;
                    if w == "PERP" { Tol::Perp { zone, datum } } else { Tol::Parlel { zone, datum } }
                }
                "ANGLB" => Tol::Anglb { angle: c.num("the nominal angle")?, lo: c.num("the lower deviation")?, hi: c.num("the upper deviation")? },
                "DISTB" => {
                    c.keyword("NOMINL")?;
                    let dist = c.num("the nominal distance")?;
                    let lo = c.num("the lower deviation")?;
                    let hi = c.num("the upper deviation")?;
                    let axis = if c.peek().is_some() {
                        Some(c.word_of("the direction", DistAxis::from_word, &words_of(DistAxis::ALL, DistAxis::word))?)
                    } else {
                        None
                    };
                    Tol::Distb { dist, lo, hi, axis }
                }
                other => {
                    return Err(c.err(c.args[0].1, ErrorKind::Unsupported, format!("TOL/{other} is not supported (FLAT, STRGHT, CIRLTY, CYLCTY, DIAM, RAD, POS, PERP, PARLEL, ANGLB, DISTB)")))
                }
            };
            Statement::Tol { label: l, tol }
        }
        "OUTPUT" => {
            no_label()?;
            let mut ls = vec![c.label(&[L::Fa, L::F, L::Ta, L::T], "what to output")?];
            while c.peek().is_some() {
                ls.push(c.label(&[L::Fa, L::F, L::Ta, L::T], "what to output")?);
            }
            Statement::Output(ls)
        }
        "TEXT" => {
            no_label()?;
            let kind =
                c.word_of("the destination", TextKind::from_word, &words_of(TextKind::ALL, TextKind::word))?;
            Statement::Text { kind, text: c.text("the text")? }
        }
        "DEVICE" => {
            let l = need_label(&[L::Did])?;
            let kind = c.word_of(
                "the device kind",
                DeviceKind::from_word,
                &words_of(DeviceKind::ALL, DeviceKind::word),
            )?;
            let file = if c.peek().is_some() { Some(c.text("the file or device name")?) } else { None };
            Statement::Device { label: l, kind, file }
        }
        "OPEN" => {
            no_label()?;
            let device = c.label(&[L::Did], "the device")?;
            let mut words = Vec::new();
            while c.peek().is_some() {
                let w = c.any_word("DIRECT, OUTPUT, OVERWR or APPEND")?;
                if !matches!(w.as_str(), "DIRECT" | "OUTPUT" | "OVERWR" | "APPEND") {
                    return Err(c.err(
                        c.args[c.k - 1].1,
                        ErrorKind::Unsupported,
                        format!("OPEN: {w} is not supported (DIRECT, OUTPUT, OVERWR, APPEND)"),
                    ));
                }
                words.push(w);
            }
            Statement::Open { device, words }
        }
        "CLOSE" => {
            no_label()?;
            let device = c.label(&[L::Did], "the device")?;
            let word = if c.peek().is_some() {
                Some(
                    c.word_of(
                        "KEEP or DELETE",
                        |w| match w {
                            "KEEP" => Some("KEEP"),
                            "DELETE" => Some("DELETE"),
                            _ => None,
                        },
                        &["KEEP", "DELETE"],
                    )?
                    .to_string(),
                )
            } else {
                None
            };
            Statement::Close { device, word }
        }
        other if OTHER_MAJORS.contains(&other) => {
            return Err(DmisError::new(
                file,
                mpos,
                ErrorKind::Unsupported,
                format!("{other} is outside the DMIS subset truepos runs (see docs/dmis.md)"),
            ))
        }
        other => {
            return Err(DmisError::new(
                file,
                mpos,
                ErrorKind::Syntax,
                format!("{other} is not a DMIS statement"),
            ))
        }
    };
    c.done()?;
    Ok(Stmt { statement: st, pos: start, label_pos: start, args: arg_pos })
}
