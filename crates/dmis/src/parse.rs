//! The parser: tokens of one statement ([`crate::lexer::RawStatement`]) → a typed
//! [`Statement`] with the positions of its parts ([`Stmt`]), and whole programs ([`parse`]).
//!
//! A statement is `[label =] MAJOR[/arg{,arg}]`; each argument is one word, number, text or
//! label. Words outside the subset are refused as [`ErrorKind::Unsupported`] at their place;
//! anything that is not DMIS as [`ErrorKind::Syntax`].

use crate::ast::*;
use crate::error::{DmisError, ErrorKind, Pos};
use crate::lexer::{statements, RawStatement, Tok};
use LabelKind as L;

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
    // CR-only line ends (classic Mac OS) make the program one statement: said as such.
    if let Some((line, col)) = truepos_io::limits::bare_carriage_return(text) {
        let at = Pos::new(u32::try_from(line).unwrap_or(u32::MAX), u32::try_from(col).unwrap_or(u32::MAX));
        return Err(DmisError::new(file, at, ErrorKind::Syntax, truepos_io::limits::CR_ONLY));
    }
    let mut out = Vec::with_capacity(text.len() / 32);
    for raw in statements(file, text) {
        out.push(parse_statement(file, &raw?)?);
    }
    Ok(Program { file: file.to_string(), statements: out })
}

/// One statement's arguments being read, left to right.
struct Cursor<'a> {
    /// The file name errors are reported with.
    file: &'a str,
    /// The major word (messages start with it).
    major: &'a str,
    /// The arguments after `/` with their positions.
    args: Vec<(&'a Tok, Pos)>,
    /// The next argument to read.
    k: usize,
    /// Just after the statement's last token.
    end: Pos,
    /// The label before `=` and its position.
    lhs: Option<(Label, Pos)>,
    /// Position of the major word.
    mpos: Pos,
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
pub(crate) const OTHER_MAJORS: &[&str] = &[
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
    let (lhs, major, mpos, arg_idx, _slash) = split(file, raw)?;
    let start = lhs.as_ref().map(|l| l.1).unwrap_or(mpos);
    let args: Vec<(&Tok, Pos)> = arg_idx.iter().map(|(k, p)| (&raw.toks[*k].0, *p)).collect();
    let arg_pos: Vec<Pos> = args.iter().map(|a| a.1).collect();
    let mut c = Cursor { file, major: &major, args, k: 0, end: raw.end, lhs, mpos };
    let st = c.statement()?;
    c.done()?;
    Ok(Stmt { statement: st, pos: start, label_pos: start, args: arg_pos })
}

/// The label before `=`: required, refused or optional, per major word.
impl Cursor<'_> {
    /// The label before `=`, which must be one of `kinds`.
    fn need_label(&self, kinds: &[LabelKind]) -> Result<Label, DmisError> {
        let names = kinds.iter().map(|k| format!("{}()", k.prefix())).collect::<Vec<_>>().join(" or ");
        let major = self.major;
        match &self.lhs {
            Some((l, _)) if kinds.contains(&l.kind) => Ok(l.clone()),
            Some((l, p)) => {
                Err(self.err(*p, ErrorKind::Syntax, format!("{major} needs a {names} label, found {l}")))
            }
            None => Err(self.err(
                self.mpos,
                ErrorKind::Syntax,
                format!("{major} needs a label: {names} = {major}/…"),
            )),
        }
    }
    /// Refuses a label before `=`.
    fn no_label(&self) -> Result<(), DmisError> {
        match &self.lhs {
            Some((l, p)) => {
                Err(self.err(*p, ErrorKind::Syntax, format!("{} takes no label ({l} =)", self.major)))
            }
            None => Ok(()),
        }
    }
    /// The label before `=`, if any, which must be one of `kinds`.
    fn opt_label(&self, kinds: &[LabelKind]) -> Result<Option<Label>, DmisError> {
        match &self.lhs {
            None => Ok(None),
            Some(_) => self.need_label(kinds).map(Some),
        }
    }
}

/// One parser per major word; each reads the arguments and leaves the check that none are left
/// over to [`parse_statement`].
impl Cursor<'_> {
    /// The statement of the major word: dispatches to its parser.
    fn statement(&mut self) -> Result<Statement, DmisError> {
        match self.major {
            "DMISMN" | "DMISMD" | "FILNAM" => self.parse_dmismn(),
            "ENDFIL" => self.no_label().map(|()| Statement::Endfil),
            "ENDMES" => self.no_label().map(|()| Statement::Endmes),
            "UNITS" => self.parse_units(),
            "DISPLY" => self.parse_disply(),
            "PRCOMP" => self.parse_prcomp(),
            "MODE" => self.parse_mode(),
            "FEDRAT" => self.parse_fedrat(),
            "SNSET" => self.parse_snset(),
            "SNSDEF" => self.parse_snsdef(),
            "SNSLCT" => {
                self.no_label()?;
                Ok(Statement::Snslct(self.label(&[L::S, L::Sa], "the sensor")?))
            }
            "SNSMNT" => self.parse_snsmnt(),
            "GOTO" => self.parse_goto(),
            "FEAT" => self.parse_feat(),
            "MEAS" => self.parse_meas(),
            "PTMEAS" => self.parse_ptmeas(),
            "CONST" => self.parse_const(),
            "DATDEF" => self.parse_datdef(),
            "DATSET" => self.parse_datset(),
            "TRANS" => self.parse_trans(),
            "ROTATE" => self.parse_rotate(),
            "SAVE" | "RECALL" => self.parse_save_recall(),
            "TOL" => self.parse_tol(),
            "OUTPUT" => self.parse_output(),
            "TEXT" => self.parse_text(),
            "DEVICE" => self.parse_device(),
            "OPEN" => self.parse_open(),
            "CLOSE" => self.parse_close(),
            other if OTHER_MAJORS.contains(&other) => Err(self.err(
                self.mpos,
                ErrorKind::Unsupported,
                format!("{other} is outside the DMIS subset truepos runs (see docs/dmis.md)"),
            )),
            other => Err(self.err(self.mpos, ErrorKind::Syntax, format!("{other} is not a DMIS statement"))),
        }
    }

    /// `DMISMN`, `DMISMD`, `FILNAM`: `'name'[,version]`.
    fn parse_dmismn(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let title = self.text("the name")?;
        let version = if self.has_num() { Some(self.num("the DMIS version")?) } else { None };
        Ok(match self.major {
            "DMISMN" => Statement::Dmismn { title, version },
            "DMISMD" => Statement::Dmismd { title, version },
            _ => Statement::Filnam { name: title, version },
        })
    }

    /// `UNITS/length,angle[,temp]`.
    fn parse_units(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let length = self.word_of(
            "the length unit",
            LengthUnit::from_word,
            &words_of(LengthUnit::ALL, LengthUnit::word),
        )?;
        let angle =
            self.word_of("the angle unit", AngleUnit::from_word, &words_of(AngleUnit::ALL, AngleUnit::word))?;
        let temp = if self.peek().is_some() {
            Some(self.word_of(
                "the temperature unit",
                TempUnit::from_word,
                &words_of(TempUnit::ALL, TempUnit::word),
            )?)
        } else {
            None
        };
        Ok(Statement::Units { length, angle, temp })
    }

    /// `DISPLY/`: words and display devices.
    fn parse_disply(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let mut items = Vec::new();
        while self.peek().is_some() {
            if self.is_label() {
                items.push(DisplyItem::Device(self.label(&[L::Did], "the display device")?));
            } else {
                let w = self.any_word("OFF, TERM, STOR, PRINT, DMIS, V or a DID() label")?;
                if !matches!(w.as_str(), "OFF" | "TERM" | "STOR" | "PRINT" | "COMM" | "DMIS" | "V") {
                    return Err(self.err(
                        self.args[self.k - 1].1,
                        ErrorKind::Unsupported,
                        format!("DISPLY: {w} is not supported (OFF, TERM, STOR, PRINT, COMM, DMIS, V)"),
                    ));
                }
                items.push(DisplyItem::Word(w));
            }
        }
        if items.is_empty() {
            return Err(self.missing("OFF or a display device"));
        }
        Ok(Statement::Disply(items))
    }

    /// `PRCOMP/ON|OFF`.
    fn parse_prcomp(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let on = self.word_of(
            "the switch",
            |w| match w {
                "ON" => Some(true),
                "OFF" => Some(false),
                _ => None,
            },
            &["ON", "OFF"],
        )?;
        Ok(Statement::Prcomp(on))
    }

    /// `MODE/word{,word}`.
    fn parse_mode(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let mut w =
            vec![self.word_of("the mode", ModeWord::from_word, &words_of(ModeWord::ALL, ModeWord::word))?];
        while self.peek().is_some() {
            w.push(self.word_of(
                "the mode",
                ModeWord::from_word,
                &words_of(ModeWord::ALL, ModeWord::word),
            )?);
        }
        Ok(Statement::Mode(w))
    }

    /// `FEDRAT/kind,unit[,value]`.
    fn parse_fedrat(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let kind =
            self.word_of("the speed", FeedKind::from_word, &words_of(FeedKind::ALL, FeedKind::word))?;
        let unit = self.word_of("the unit", FeedUnit::from_word, &words_of(FeedUnit::ALL, FeedUnit::word))?;
        let value = match unit {
            FeedUnit::High | FeedUnit::Low | FeedUnit::Defalt => None,
            _ => Some(self.num("the speed")?),
        };
        Ok(Statement::Fedrat { kind, unit, value })
    }

    /// `SNSET/APPRCH|RETRCT|SEARCH|DEPTH|CLRSRF,…`.
    fn parse_snset(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let w = self.any_word("APPRCH, RETRCT, SEARCH, DEPTH or CLRSRF")?;
        let it = match w.as_str() {
            "APPRCH" => Snset::Apprch(self.num("the approach distance")?),
            "RETRCT" => Snset::Retrct(self.num("the retract distance")?),
            "SEARCH" => Snset::Search(self.num("the search distance")?),
            "DEPTH" => Snset::Depth(self.num("the depth")?),
            "CLRSRF" => {
                if self.is_word("OFF") {
                    self.k += 1;
                    Snset::ClrsrfOff
                } else {
                    let f = if self.is_label() {
                        Some(self.label(&[L::F, L::Fa], "the clearance plane")?)
                    } else {
                        None
                    };
                    Snset::Clrsrf(f, self.num("the clearance distance")?)
                }
            }
            other => {
                return Err(self.err(
                    self.args[0].1,
                    ErrorKind::Unsupported,
                    format!("SNSET/{other} is not supported (APPRCH, RETRCT, SEARCH, DEPTH, CLRSRF)"),
                ))
            }
        };
        Ok(Statement::Snset(it))
    }

    /// `S(l)=SNSDEF/PROBE,FIXED,CART,x,y,z,i,j,k,diam`.
    fn parse_snsdef(&mut self) -> Result<Statement, DmisError> {
        let label = self.need_label(&[L::S])?;
        self.keyword("PROBE")?;
        self.keyword("FIXED")?;
        self.keyword("CART")?;
        let offset = self.xyz("the probe offset")?;
        let dir = self.xyz("the probe direction")?;
        let diam = self.num("the tip diameter")?;
        Ok(Statement::Snsdef { label, offset, dir, diam })
    }

    /// `SNSMNT/XVEC,i,j,k,ZVEC,i,j,k,MNTLEN,x,y,z`.
    fn parse_snsmnt(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        self.keyword("XVEC")?;
        let xvec = self.xyz("XVEC")?;
        self.keyword("ZVEC")?;
        let zvec = self.xyz("ZVEC")?;
        self.keyword("MNTLEN")?;
        let mntlen = self.xyz("MNTLEN")?;
        Ok(Statement::Snsmnt { xvec, zvec, mntlen })
    }

    /// `GOTO/[CART,]x,y,z` or `GOTO/INCR,dist,i,j,k`.
    fn parse_goto(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        if self.is_word("INCR") {
            self.k += 1;
            let dist = self.num("the distance")?;
            Ok(Statement::Goto(Goto::Incr { dist, dir: self.xyz("the direction")? }))
        } else {
            if self.is_word("CART") {
                self.k += 1;
            }
            Ok(Statement::Goto(Goto::Abs(self.xyz("the target")?)))
        }
    }

    /// `F(l)=FEAT/type,…`.
    fn parse_feat(&mut self) -> Result<Statement, DmisError> {
        let label = self.need_label(&[L::F, L::Fa])?;
        let ft =
            self.word_of("the feature type", FeatType::from_word, &words_of(FeatType::ALL, FeatType::word))?;
        let geom = self.feat_geom(ft)?;
        Ok(Statement::Feat { label, geom })
    }

    /// The arguments of `FEAT/` after the feature type `ft`.
    fn feat_geom(&mut self, ft: FeatType) -> Result<FeatGeom, DmisError> {
        Ok(match ft {
            FeatType::Point | FeatType::Plane => {
                self.keyword("CART")?;
                let p = self.xyz("the point")?;
                let n = self.xyz("the normal")?;
                if ft == FeatType::Point {
                    FeatGeom::Point { p, n }
                } else {
                    FeatGeom::Plane { p, n }
                }
            }
            FeatType::Line => {
                let bnd = self.word_of(
                    "UNBND or BND",
                    |w| match w {
                        "UNBND" => Some(false),
                        "BND" => Some(true),
                        _ => None,
                    },
                    &["UNBND", "BND"],
                )?;
                self.keyword("CART")?;
                let a = self.xyz(if bnd { "the start point" } else { "the point" })?;
                let b = self.xyz(if bnd { "the end point" } else { "the direction" })?;
                let plane = if self.has_num() { Some(self.xyz("the plane normal")?) } else { None };
                if bnd {
                    FeatGeom::LineBnd { p1: a, p2: b, plane }
                } else {
                    FeatGeom::LineUnbnd { p: a, dir: b, plane }
                }
            }
            FeatType::Circle => {
                let side = self.side()?;
                self.keyword("CART")?;
                FeatGeom::Circle {
                    side,
                    c: self.xyz("the centre")?,
                    n: self.xyz("the normal")?,
                    diam: self.num("the diameter")?,
                }
            }
            FeatType::Cylndr => {
                let side = self.side()?;
                self.keyword("CART")?;
                let p = self.xyz("the axis point")?;
                let axis = self.xyz("the axis")?;
                let diam = self.num("the diameter")?;
                let length = if self.has_num() { Some(self.num("the length")?) } else { None };
                FeatGeom::Cylndr { side, p, axis, diam, length }
            }
            FeatType::Sphere => {
                let side = self.side()?;
                self.keyword("CART")?;
                let cc = self.xyz("the centre")?;
                let n = if self.count_nums() >= 4 { Some(self.xyz("the direction")?) } else { None };
                FeatGeom::Sphere { side, c: cc, n, diam: self.num("the diameter")? }
            }
            FeatType::Cone => {
                let side = self.side()?;
                self.keyword("CART")?;
                FeatGeom::Cone {
                    side,
                    apex: self.xyz("the apex")?,
                    axis: self.xyz("the axis")?,
                    angle: self.num("the included angle")?,
                }
            }
        })
    }

    /// `MEAS/type,F(l),n`.
    fn parse_meas(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let ftype =
            self.word_of("the feature type", FeatType::from_word, &words_of(FeatType::ALL, FeatType::word))?;
        let feature = self.label(&[L::F], "the feature")?;
        let p = self.here();
        let n = self.num("the number of points")?;
        if !((1.0..=100_000.0).contains(&n) && n.fract() == 0.0) {
            return Err(self.err(
                p,
                ErrorKind::Syntax,
                format!("MEAS: the number of points must be a whole number from 1 to 100000, not {n}"),
            ));
        }
        Ok(Statement::Meas { ftype, feature, n: n as u32 })
    }

    /// `PTMEAS/CART,x,y,z[,i,j,k]`.
    fn parse_ptmeas(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        self.keyword("CART")?;
        let p = self.xyz("the point")?;
        let n = if self.has_num() { Some(self.xyz("the approach direction")?) } else { None };
        Ok(Statement::Ptmeas { p, n })
    }

    /// `CONST/type,F(l),BF|INTOF|PROJCT|MIDPT,…`.
    fn parse_const(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let ftype =
            self.word_of("the feature type", FeatType::from_word, &words_of(FeatType::ALL, FeatType::word))?;
        let feature = self.label(&[L::F], "the constructed feature")?;
        let m = self.any_word("BF, INTOF, PROJCT or MIDPT")?;
        let src = &[L::Fa, L::F];
        let method = match m.as_str() {
            "BF" => {
                let mut ls = vec![self.label(src, "a feature")?];
                while self.peek().is_some() {
                    ls.push(self.label(src, "a feature")?);
                }
                ConstMethod::Bf(ls)
            }
            "INTOF" => ConstMethod::Intof(
                self.label(src, "the first feature")?,
                self.label(src, "the second feature")?,
            ),
            "PROJCT" => {
                ConstMethod::Projct(self.label(src, "the feature to project")?, self.label(src, "the plane")?)
            }
            "MIDPT" => ConstMethod::Midpt(
                self.label(src, "the first feature")?,
                self.label(src, "the second feature")?,
            ),
            other => {
                return Err(self.err(
                    self.args[2].1,
                    ErrorKind::Unsupported,
                    format!("CONST: {other} is not supported (BF, INTOF, PROJCT, MIDPT)"),
                ))
            }
        };
        Ok(Statement::Const { ftype, feature, method })
    }

    /// `DAT(A)=DATDEF/FA(x)` or DMIS 3's `DATDEF/FA(x),DA(A)`.
    fn parse_datdef(&mut self) -> Result<Statement, DmisError> {
        if self.lhs.is_some() {
            let datum = self.need_label(&[L::Dat, L::Da])?;
            Ok(Statement::Datdef {
                datum,
                feature: self.label(&[L::Fa, L::F], "the datum feature")?,
                assigned: true,
            })
        } else {
            let feature = self.label(&[L::Fa, L::F], "the datum feature")?;
            Ok(Statement::Datdef {
                feature,
                datum: self.label(&[L::Dat, L::Da], "the datum")?,
                assigned: false,
            })
        }
    }

    /// `D(l)=DATSET/MCS` or `D(l)=DATSET/DAT(A),word{,word}{,DAT(B),word{,word}}`.
    fn parse_datset(&mut self) -> Result<Statement, DmisError> {
        let l = self.need_label(&[L::D])?;
        if self.is_word("MCS") {
            self.k += 1;
            return Ok(Statement::Datset { label: l, def: Datset::Mcs });
        }
        let mut ds = Vec::new();
        while self.peek().is_some() {
            let d = self.label(&[L::Dat, L::Da, L::Fa], "a datum")?;
            let mut ws = Vec::new();
            while matches!(self.peek(), Some(Tok::Word(_))) {
                ws.push(self.word_of(
                    "an axis or origin",
                    DatsetWord::from_word,
                    &words_of(DatsetWord::ALL, DatsetWord::word),
                )?);
            }
            if ws.is_empty() {
                return Err(self.missing("an axis or origin (XDIR, YDIR, ZDIR, XORIG, YORIG, ZORIG)"));
            }
            ds.push((d, ws));
        }
        if ds.is_empty() {
            return Err(self.missing("MCS or datums"));
        }
        Ok(Statement::Datset { label: l, def: Datset::Datums(ds) })
    }

    /// `[D(l)=]TRANS/origin,value|FA(x){,origin,value|FA(x)}`.
    fn parse_trans(&mut self) -> Result<Statement, DmisError> {
        let l = self.opt_label(&[L::D])?;
        let mut items = Vec::new();
        loop {
            let o = self.word_of("the origin", Origin::from_word, &words_of(Origin::ALL, Origin::word))?;
            let by = if self.is_label() {
                TransBy::Feature(self.label(&[L::Fa, L::F], "the feature")?)
            } else {
                TransBy::Value(self.num("the new origin")?)
            };
            items.push((o, by));
            if self.peek().is_none() {
                break;
            }
        }
        Ok(Statement::Trans { label: l, items })
    }

    /// `[D(l)=]ROTATE/axis,angle` or `[D(l)=]ROTATE/axis,FA(x),direction`.
    fn parse_rotate(&mut self) -> Result<Statement, DmisError> {
        let l = self.opt_label(&[L::D])?;
        let axis = self.word_of("the axis", RotAxis::from_word, &words_of(RotAxis::ALL, RotAxis::word))?;
        let by = if self.is_label() {
            let f = self.label(&[L::Fa, L::F], "the feature")?;
            RotateBy::Feature(
                f,
                self.word_of("the direction", AxisDir::from_word, &words_of(AxisDir::ALL, AxisDir::word))?,
            )
        } else {
            RotateBy::Angle(self.num("the angle")?)
        };
        Ok(Statement::Rotate { label: l, axis, by })
    }

    /// `SAVE/D(l)` or `RECALL/D(l)`.
    fn parse_save_recall(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let l = self.label(&[L::D, L::Da], "the coordinate system")?;
        Ok(if self.major == "SAVE" { Statement::Save(l) } else { Statement::Recall(l) })
    }

    /// `T(l)=TOL/kind,…`.
    fn parse_tol(&mut self) -> Result<Statement, DmisError> {
        let l = self.need_label(&[L::T])?;
        let w = self.any_word("the tolerance kind")?;
        let tol = match w.as_str() {
            "FLAT" => Tol::Flat(self.num("the zone")?),
            "STRGHT" => Tol::Strght(self.num("the zone")?),
            "CIRLTY" => Tol::Cirlty(self.num("the zone")?),
            "CYLCTY" => Tol::Cylcty(self.num("the zone")?),
            "DIAM" => {
                Tol::Diam { lo: self.num("the lower deviation")?, hi: self.num("the upper deviation")? }
            }
            "RAD" => Tol::Rad { lo: self.num("the lower deviation")?, hi: self.num("the upper deviation")? },
            "POS" => self.tol_pos()?,
            "PERP" | "PARLEL" => {
                let zone = self.num("the zone")?;
                let datum = self.label(&[L::Dat, L::Da, L::Fa, L::F], "the datum")?;
                if w == "PERP" {
                    Tol::Perp { zone, datum }
                } else {
                    Tol::Parlel { zone, datum }
                }
            }
            "ANGLB" => Tol::Anglb {
                angle: self.num("the nominal angle")?,
                lo: self.num("the lower deviation")?,
                hi: self.num("the upper deviation")?,
            },
            "DISTB" => self.tol_distb()?,
            other => {
                return Err(self.err(
                    self.args[0].1,
                    ErrorKind::Unsupported,
                    format!(
                        "TOL/{other} is not supported \
                         (FLAT, STRGHT, CIRLTY, CYLCTY, DIAM, RAD, POS, PERP, PARLEL, ANGLB, DISTB)"
                    ),
                ))
            }
        };
        Ok(Statement::Tol { label: l, tol })
    }

    /// The arguments of `TOL/POS`: `2D|3D,zone,condition{,datum}`.
    fn tol_pos(&mut self) -> Result<Tol, DmisError> {
        let three_d = self.word_of(
            "2D or 3D",
            |w| match w {
                "2D" => Some(false),
                "3D" => Some(true),
                _ => None,
            },
            &["2D", "3D"],
        )?;
        let zone = self.num("the zone diameter")?;
        let cond = self.word_of(
            "the material condition",
            MatCond::from_word,
            &words_of(MatCond::ALL, MatCond::word),
        )?;
        let mut datums = Vec::new();
        while self.peek().is_some() {
            datums.push(self.label(&[L::Dat, L::Da], "a datum")?);
        }
        Ok(Tol::Pos { three_d, zone, cond, datums })
    }

    /// The arguments of `TOL/DISTB`: `NOMINL,dist,lotol,uptol[,axis]`.
    fn tol_distb(&mut self) -> Result<Tol, DmisError> {
        self.keyword("NOMINL")?;
        let dist = self.num("the nominal distance")?;
        let lo = self.num("the lower deviation")?;
        let hi = self.num("the upper deviation")?;
        let axis = if self.peek().is_some() {
            Some(self.word_of(
                "the direction",
                DistAxis::from_word,
                &words_of(DistAxis::ALL, DistAxis::word),
            )?)
        } else {
            None
        };
        Ok(Tol::Distb { dist, lo, hi, axis })
    }

    /// `OUTPUT/label{,label}`.
    fn parse_output(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let mut ls = vec![self.label(&[L::Fa, L::F, L::Ta, L::T], "what to output")?];
        while self.peek().is_some() {
            ls.push(self.label(&[L::Fa, L::F, L::Ta, L::T], "what to output")?);
        }
        Ok(Statement::Output(ls))
    }

    /// `TEXT/kind,'text'`.
    fn parse_text(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let kind =
            self.word_of("the destination", TextKind::from_word, &words_of(TextKind::ALL, TextKind::word))?;
        Ok(Statement::Text { kind, text: self.text("the text")? })
    }

    /// `DID(l)=DEVICE/kind[,'file']`.
    fn parse_device(&mut self) -> Result<Statement, DmisError> {
        let l = self.need_label(&[L::Did])?;
        let kind = self.word_of(
            "the device kind",
            DeviceKind::from_word,
            &words_of(DeviceKind::ALL, DeviceKind::word),
        )?;
        let file = if self.peek().is_some() { Some(self.text("the file or device name")?) } else { None };
        Ok(Statement::Device { label: l, kind, file })
    }

    /// `OPEN/DID(l){,word}`.
    fn parse_open(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let device = self.label(&[L::Did], "the device")?;
        let mut words = Vec::new();
        while self.peek().is_some() {
            let w = self.any_word("DIRECT, OUTPUT, OVERWR or APPEND")?;
            if !matches!(w.as_str(), "DIRECT" | "OUTPUT" | "OVERWR" | "APPEND") {
                return Err(self.err(
                    self.args[self.k - 1].1,
                    ErrorKind::Unsupported,
                    format!("OPEN: {w} is not supported (DIRECT, OUTPUT, OVERWR, APPEND)"),
                ));
            }
            words.push(w);
        }
        Ok(Statement::Open { device, words })
    }

    /// `CLOSE/DID(l)[,KEEP|DELETE]`.
    fn parse_close(&mut self) -> Result<Statement, DmisError> {
        self.no_label()?;
        let device = self.label(&[L::Did], "the device")?;
        let word = if self.peek().is_some() {
            Some(
                self.word_of(
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
        Ok(Statement::Close { device, word })
    }
}
