//! The formula language: a recursive-descent parser from text to an
//! expression tree.
//!
//! ```text
//! formula := sum
//! sum     := product (("+" | "−") product)*
//! product := unary (("*" | "/") unary)*
//! unary   := ("−" | "+") unary | power
//! power   := atom ("^" unary)?            right-associative: 2^3^2 = 2^9
//! atom    := number | "x" | "y" | "z" | "pi" | "e"
//!          | function "(" sum ("," sum)* ")" | "(" sum ")"
//! ```
//!
//! `-x^2` is `−(x²)`, as in mathematics. Functions: `sqrt abs sin cos exp ln`
//! of one argument, `min max` of two.

use std::fmt;

/// An error in a formula, at a 1-based character column.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("column {column}: {message}")]
pub struct FormulaError {
    pub column: usize,
    pub message: String,
}

/// Functions of the formula language.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Func {
    Sqrt,
    Abs,
    Sin,
    Cos,
    Exp,
    Ln,
    Min,
    Max,
}

impl Func {
    const ALL: [(&'static str, Func, usize); 8] = [
        ("sqrt", Func::Sqrt, 1),
        ("abs", Func::Abs, 1),
        ("sin", Func::Sin, 1),
        ("cos", Func::Cos, 1),
        ("exp", Func::Exp, 1),
        ("ln", Func::Ln, 1),
        ("min", Func::Min, 2),
        ("max", Func::Max, 2),
    ];
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    Pow,
}

/// An expression tree. Variables are 0 = x, 1 = y, 2 = z.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    Num(f64),
    Var(u8),
    Neg(Box<Expr>),
    Binary(BinOp, Box<Expr>, Box<Expr>),
    Call(Func, Vec<Expr>),
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Num(f64),
    Name(String),
    Sym(char),
    End,
}

impl fmt::Display for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Token::Num(n) => write!(f, "number `{n}`"),
            Token::Name(s) => write!(f, "`{s}`"),
            Token::Sym(c) => write!(f, "`{c}`"),
            Token::End => f.write_str("the end of the formula"),
        }
    }
}

/// Splits the text into tokens, each with its 1-based column.
fn tokenize(text: &str) -> Result<Vec<(Token, usize)>, FormulaError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let column = i + 1;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit()
            || (c == '.' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit()))
        {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    i = j;
                    while i < chars.len() && chars[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            }
            let s: String = chars[start..i].iter().collect();
            let n = s.parse::<f64>().map_err(|_| FormulaError {
                column,
                message: format!("malformed number `{s}`"),
            })?;
            out.push((Token::Num(n), column));
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push((Token::Name(chars[start..i].iter().collect()), column));
        } else if "+-*/^(),".contains(c) {
            out.push((Token::Sym(c), column));
            i += 1;
        } else if c == '−' {
            // U+2212 MINUS SIGN, as typed from mathematical text.
            out.push((Token::Sym('-'), column));
            i += 1;
        } else {
            return Err(FormulaError {
                column,
                message: format!("unexpected character `{c}`"),
            });
        }
    }
    out.push((Token::End, chars.len() + 1));
    Ok(out)
}

/// How deeply a formula may nest parentheses, function calls, signs and
/// exponents: the parser recurses once per level, and a formula nested
/// 10,000 deep would overflow its stack.
pub const MAX_NESTING: usize = 100;

/// The greatest height of a formula's expression tree (a chain `a + b + …`
/// of n terms is n high): compiling and dropping the tree recurse over it.
/// Formulas that high exceed the tape's [`super::MAX_TAPE`] operations anyway,
/// unless they fold to constants.
pub const MAX_HEIGHT: u32 = 1000;

/// Parses a formula in x, y, z.
pub fn parse(text: &str) -> Result<Expr, FormulaError> {
    let tokens = tokenize(text)?;
    let mut p = Parser {
        tokens,
        pos: 0,
        depth: 0,
    };
    let (e, _) = p.sum()?;
    match p.peek() {
        Token::End => Ok(e),
        Token::Sym(')') => Err(p.error("unmatched `)`".into())),
        Token::Num(_) | Token::Name(_) | Token::Sym('(') => Err(p.error(format!(
            "expected an operator before {} (multiplication is written `*`, e.g. `2*x`)",
            p.peek()
        ))),
        t => Err(p.error(format!("unexpected {t}"))),
    }
}

struct Parser {
    tokens: Vec<(Token, usize)>,
    pos: usize,
    /// Current nesting depth (see [`MAX_NESTING`]).
    depth: usize,
}

/// A parsed subexpression and the height of its tree.
type Node = (Expr, u32);

/// `op(a, b)`, unless the tree would be higher than [`MAX_HEIGHT`].
fn binary(op: BinOp, (a, ha): Node, (b, hb): Node, column: usize) -> Result<Node, FormulaError> {
    let h = ha.max(hb) + 1;
    if h > MAX_HEIGHT {
        return Err(FormulaError {
            column,
            message: format!(
                "the formula is too long: its expression tree is more than {MAX_HEIGHT} operations deep"
            ),
        });
    }
    Ok((Expr::Binary(op, Box::new(a), Box::new(b)), h))
}

impl Parser {
    fn peek(&self) -> &Token {
        &self.tokens[self.pos].0
    }

    fn column(&self) -> usize {
        self.tokens[self.pos].1
    }

    fn error(&self, message: String) -> FormulaError {
        FormulaError {
            column: self.column(),
            message,
        }
    }

    fn advance(&mut self) -> Token {
        let t = self.tokens[self.pos].0.clone();
        if self.pos + 1 < self.tokens.len() {
            self.pos += 1;
        }
        t
    }

    fn eat(&mut self, c: char) -> bool {
        if *self.peek() == Token::Sym(c) {
            self.advance();
            true
        } else {
            false
        }
    }

    /// Runs `parse` one nesting level deeper, or fails past [`MAX_NESTING`].
    fn nested(
        &mut self,
        parse: impl FnOnce(&mut Self) -> Result<Node, FormulaError>,
    ) -> Result<Node, FormulaError> {
        if self.depth >= MAX_NESTING {
            return Err(self.error(format!(
                "the formula nests parentheses, functions, signs or powers more than {MAX_NESTING} levels deep"
            )));
        }
        self.depth += 1;
        let node = parse(self);
        self.depth -= 1;
        node
    }

    fn sum(&mut self) -> Result<Node, FormulaError> {
        let mut e = self.product()?;
        loop {
            let op = match self.peek() {
                Token::Sym('+') => BinOp::Add,
                Token::Sym('-') => BinOp::Sub,
                _ => return Ok(e),
            };
            let column = self.column();
            self.advance();
            e = binary(op, e, self.product()?, column)?;
        }
    }

    fn product(&mut self) -> Result<Node, FormulaError> {
        let mut e = self.unary()?;
        loop {
            let op = match self.peek() {
                Token::Sym('*') => BinOp::Mul,
                Token::Sym('/') => BinOp::Div,
                _ => return Ok(e),
            };
            let column = self.column();
            self.advance();
            e = binary(op, e, self.unary()?, column)?;
        }
    }

    fn unary(&mut self) -> Result<Node, FormulaError> {
        if self.eat('-') {
            let (e, h) = self.nested(Self::unary)?;
            return Ok((Expr::Neg(Box::new(e)), h + 1));
        }
        if self.eat('+') {
            return self.nested(Self::unary);
        }
        self.power()
    }

    fn power(&mut self) -> Result<Node, FormulaError> {
        let base = self.atom()?;
        let column = self.column();
        if self.eat('^') {
            let exponent = self.nested(Self::unary)?;
            return binary(BinOp::Pow, base, exponent, column);
        }
        Ok(base)
    }

    fn atom(&mut self) -> Result<Node, FormulaError> {
        let column = self.column();
        match self.advance() {
            Token::Num(n) => Ok((Expr::Num(n), 1)),
            Token::Sym('(') => {
                let e = self.nested(Self::sum)?;
                if !self.eat(')') {
                    return Err(self.error(format!(
                        "expected `)` to close the `(` at column {column}, found {}",
                        self.peek()
                    )));
                }
                Ok(e)
            }
            Token::Name(name) => self.name(&name, column),
            t => {
                self.pos -= usize::from(t != Token::End);
                Err(FormulaError {
                    column,
                    message: format!("expected a number, variable, function or `(`, found {t}"),
                })
            }
        }
    }

    fn name(&mut self, name: &str, column: usize) -> Result<Node, FormulaError> {
        let leaf = match name {
            "x" => Some(Expr::Var(0)),
            "y" => Some(Expr::Var(1)),
            "z" => Some(Expr::Var(2)),
            "pi" => Some(Expr::Num(std::f64::consts::PI)),
            "e" => Some(Expr::Num(std::f64::consts::E)),
            _ => None,
        };
        if let Some(leaf) = leaf {
            return Ok((leaf, 1));
        }
        let Some(&(_, func, arity)) = Func::ALL.iter().find(|(n, _, _)| *n == name) else {
            let names: Vec<&str> = Func::ALL.iter().map(|(n, _, _)| *n).collect();
            return Err(FormulaError {
                column,
                message: format!(
                    "unknown name `{name}`; expected x, y, z, pi, e or a function: {}",
                    names.join(", ")
                ),
            });
        };
        if !self.eat('(') {
            return Err(self.error(format!("expected `(` after the function `{name}`")));
        }
        let mut args = vec![self.nested(Self::sum)?];
        while self.eat(',') {
            args.push(self.nested(Self::sum)?);
        }
        if !self.eat(')') {
            return Err(self.error(format!(
                "expected `,` or `)` in the arguments of `{name}`, found {}",
                self.peek()
            )));
        }
        if args.len() != arity {
            return Err(FormulaError {
                column,
                message: format!(
                    "`{name}` takes {arity} argument{}, found {}",
                    if arity == 1 { "" } else { "s" },
                    args.len()
                ),
            });
        }
        let height = args.iter().map(|a| a.1).max().unwrap_or(0) + 1;
        if height > MAX_HEIGHT {
            return Err(FormulaError {
                column,
                message: format!(
                    "the formula is too long: its expression tree is more than {MAX_HEIGHT} operations deep"
                ),
            });
        }
        Ok((
            Expr::Call(func, args.into_iter().map(|a| a.0).collect()),
            height,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> (usize, String) {
        let e = parse(text).unwrap_err();
        (e.column, e.message)
    }

    #[test]
    fn precedence_and_associativity() {
        use Expr::*;
        let x = || Box::new(Var(0));
        assert_eq!(
            parse("-x^2").unwrap(),
            Neg(Box::new(Binary(BinOp::Pow, x(), Box::new(Num(2.0)))))
        );
        assert_eq!(
            parse("2^3^2").unwrap(),
            Binary(
                BinOp::Pow,
                Box::new(Num(2.0)),
                Box::new(Binary(BinOp::Pow, Box::new(Num(3.0)), Box::new(Num(2.0))))
            )
        );
        assert_eq!(
            parse("x - y - z").unwrap(),
            Binary(
                BinOp::Sub,
                Box::new(Binary(BinOp::Sub, x(), Box::new(Var(1)))),
                Box::new(Var(2))
            )
        );
        assert!(parse("x^-2").is_ok());
        assert!(parse("1.5e-3 * .5 + 2E2").is_ok());
        assert!(parse("(x² )").is_err());
        assert!(parse("x − y").is_ok());
    }

    #[test]
    fn deep_nesting_is_an_error_not_a_stack_overflow() {
        let n = 10_000;
        for (text, what) in [
            (format!("{}x{}", "(".repeat(n), ")".repeat(n)), "nests"),
            (format!("{}x{}", "sqrt(".repeat(n), ")".repeat(n)), "nests"),
            (format!("{}x", "-".repeat(n)), "nests"),
            (format!("{}x", "+".repeat(n)), "nests"),
            (format!("x{}", "^x".repeat(n)), "nests"),
            (format!("x{}", "+x".repeat(n)), "deep"),
            (format!("1{}", "*1".repeat(n)), "deep"),
        ] {
            let e = parse(&text).unwrap_err();
            assert!(e.message.contains(what), "{}: {}", &text[..20], e.message);
            assert!(e.column > 1 && e.column <= text.chars().count(), "{e}");
        }
        // Just inside the limits.
        let ok = format!(
            "{}x{}",
            "(".repeat(MAX_NESTING - 1),
            ")".repeat(MAX_NESTING - 1)
        );
        assert!(parse(&ok).is_ok());
        let ok = format!("x{}", "+x".repeat(MAX_HEIGHT as usize - 1));
        assert!(parse(&ok).is_ok());
    }

    #[test]
    fn errors_point_at_the_column() {
        assert_eq!(err("x + * y").0, 5);
        assert_eq!(err("x^2 + w").0, 7);
        assert!(err("x^2 + w").1.contains("unknown name `w`"));
        assert_eq!(err("(x + y").0, 7);
        assert!(err("(x + y").1.contains("to close the `(` at column 1"));
        assert_eq!(err("x + y)").0, 6);
        assert_eq!(err("2x").0, 2);
        assert!(err("2x").1.contains("`2*x`"));
        assert_eq!(err("sqrt x").0, 6);
        assert_eq!(err("min(x)").0, 1);
        assert!(err("min(x)").1.contains("takes 2 arguments"));
        assert_eq!(err("x + 1..2").0, 5);
        assert_eq!(err("x # y").0, 3);
        assert_eq!(err("").0, 1);
        assert_eq!(err("x +").0, 4);
    }
}
