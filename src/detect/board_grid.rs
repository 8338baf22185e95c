//! A board's size as given on the command line: `COLSxROWS`.

/// A board's inner corners from `COLSxROWS` (the command line's `--board`).
pub fn parse_board(text: &str) -> Result<[u32; 2], GridError> {
    parse_grid(text, crate::core::limits::MAX_BOARD_CORNERS, "inner corners")
}

/// A ChArUco board's squares `XxY` from the command line (2 to 101 a side,
/// as in manifests).
pub fn parse_squares(text: &str) -> Result<[u32; 2], GridError> {
    parse_grid(text, crate::core::limits::MAX_BOARD_CORNERS + 1, "squares")
}

/// Why a board's `COLSxROWS` is not taken.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    #[error("`{0}` is not COLSxROWS (e.g. 9x6)")]
    Syntax(String),
    #[error("a board needs at least 2x2 {what}, got {c}x{r}")]
    TooSmall { what: &'static str, c: u32, r: u32 },
    #[error("a board has at most {most} {what} a side, got {c}x{r}")]
    TooLarge {
        what: &'static str,
        most: u32,
        c: u32,
        r: u32,
    },
}

/// `COLSxROWS`, each 2 to `most` (a board larger than any printed one would
/// ask for gigabytes of corners).
fn parse_grid(text: &str, most: u32, what: &'static str) -> Result<[u32; 2], GridError> {
    let syntax = || GridError::Syntax(text.to_string());
    let (c, r) = text.split_once(['x', 'X']).ok_or_else(syntax)?;
    let parse = |s: &str| s.trim().parse::<u32>().map_err(|_| syntax());
    let (c, r) = (parse(c)?, parse(r)?);
    if c < 2 || r < 2 {
        return Err(GridError::TooSmall { what, c, r });
    }
    if c > most || r > most {
        return Err(GridError::TooLarge { what, most, c, r });
    }
    Ok([c, r])
}
