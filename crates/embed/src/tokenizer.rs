//! BERT's WordPiece tokenizer, as the Hugging Face tokenizer of all-MiniLM-L6-v2
//! (`BertTokenizerFast`, `tokenizer.json`) runs it:
//!
//! 1. **special tokens** written in the text (`[CLS]`, `[SEP]`, `[PAD]`, `[UNK]`, `[MASK]`)
//!    are cut out first and keep their ids;
//! 2. **normalisation** (BertNormalizer): NUL, U+FFFD and control characters (Unicode
//!    categories Cc, Cf, Cn, Co, Cs except tab, newline and carriage return) are dropped,
//!    whitespace becomes a space, CJK ideographs are padded with spaces; with lower-casing,
//!    accents are stripped (NFD, then nonspacing marks Mn dropped) and every character is
//!    lower-cased (`char::to_lowercase`);
//! 3. **pre-tokenisation** (BertPreTokenizer): split on whitespace, and every punctuation
//!    character (ASCII punctuation, or Unicode categories Pc, Pd, Pe, Pf, Pi, Po, Ps) is a
//!    token of its own;
//! 4. **WordPiece**: each word is cut greedily into the longest vocabulary pieces from the
//!    left (continuations prefixed `##`); a word with a piece not in the vocabulary, or longer
//!    than 100 characters, becomes `[UNK]`;
//! 5. `[CLS] … [SEP]` around the ids, the text truncated to `max_tokens − 2` pieces.
//!
//! Cost: linear in the text's length (a vocabulary look-up per candidate piece).

use std::collections::HashMap;

use unicode_general_category::{GeneralCategory, get_general_category};
use unicode_normalization::UnicodeNormalization;

/// Longest word WordPiece cuts (longer ones are `[UNK]`).
const MAX_WORD_CHARS: usize = 100;

/// The special tokens every BERT vocabulary holds.
const SPECIALS: [&str; 5] = ["[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]"];

/// A WordPiece tokenizer with BERT-uncased's basic tokenization.
#[derive(Clone)]
pub struct Tokenizer {
    vocab: HashMap<String, u32>,
    lowercase: bool,
    max_tokens: usize,
    unk: u32,
    cls: u32,
    sep: u32,
    specials: Vec<(&'static str, u32)>,
}

/// The settings and the vocabulary's size (not its 30,000 entries).
impl std::fmt::Debug for Tokenizer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Tokenizer")
            .field("vocab_size", &self.vocab.len())
            .field("lowercase", &self.lowercase)
            .field("max_tokens", &self.max_tokens)
            .finish_non_exhaustive()
    }
}

impl Tokenizer {
    /// A tokenizer over `vocab_txt` (one token per line, the line number its id), lower-casing
    /// (and stripping accents) when `lowercase`, producing at most `max_tokens` ids
    /// (`[CLS]` and `[SEP]` included; at least 2).
    pub fn from_vocab(vocab_txt: &str, lowercase: bool, max_tokens: usize) -> Result<Self, String> {
        let mut vocab = HashMap::new();
        for (i, line) in vocab_txt.lines().enumerate() {
            let id = u32::try_from(i).map_err(|_| "the vocabulary is too large".to_string())?;
            // The first occurrence of a token keeps its id, as the reference loader does.
            vocab.entry(line.to_string()).or_insert(id);
        }
        let id = |t: &str| {
            vocab
                .get(t)
                .copied()
                .ok_or_else(|| format!("the vocabulary lacks the special token {t}"))
        };
        let specials = SPECIALS
            .into_iter()
            .map(|t| id(t).map(|i| (t, i)))
            .collect::<Result<Vec<_>, _>>()?;
        if max_tokens < 2 {
            return Err(format!(
                "max_tokens {max_tokens}: at least 2 ([CLS] and [SEP])"
            ));
        }
        Ok(Self {
            unk: id("[UNK]")?,
            cls: id("[CLS]")?,
            sep: id("[SEP]")?,
            vocab,
            lowercase,
            max_tokens,
            specials,
        })
    }

    /// The vocabulary's size.
    pub fn vocab_size(&self) -> usize {
        self.vocab.len()
    }

    /// The most ids [`encode`](Self::encode) returns.
    pub fn max_tokens(&self) -> usize {
        self.max_tokens
    }

    /// The ids the model reads: `[CLS]`, the text's pieces (truncated), `[SEP]`.
    pub fn encode(&self, text: &str) -> Vec<u32> {
        let mut ids = Vec::with_capacity(16);
        ids.push(self.cls);
        self.pieces(text, &mut |_, id| ids.push(id));
        ids.truncate(self.max_tokens - 1);
        ids.push(self.sep);
        ids
    }

    /// The text's word pieces (no `[CLS]`/`[SEP]`, not truncated), as strings.
    pub fn tokenize(&self, text: &str) -> Vec<String> {
        let mut out = Vec::new();
        self.pieces(text, &mut |piece, _| out.push(piece.to_string()));
        out
    }

    /// Calls `emit(piece, id)` for every piece of `text`.
    fn pieces(&self, text: &str, emit: &mut dyn FnMut(&str, u32)) {
        let mut rest = text;
        loop {
            // The leftmost special token written in the text (ties: the longest).
            let next = self
                .specials
                .iter()
                .filter_map(|&(t, id)| rest.find(t).map(|at| (at, t, id)))
                .min_by_key(|&(at, t, _)| (at, std::cmp::Reverse(t.len())));
            match next {
                Some((at, t, id)) => {
                    self.plain_pieces(&rest[..at], emit);
                    emit(t, id);
                    rest = &rest[at + t.len()..];
                }
                None => {
                    self.plain_pieces(rest, emit);
                    return;
                }
            }
        }
    }

    fn plain_pieces(&self, text: &str, emit: &mut dyn FnMut(&str, u32)) {
        if text.is_empty() {
            return;
        }
        let normalized = self.normalize(text);
        for word in normalized.split(char::is_whitespace) {
            let mut start = 0;
            for (i, c) in word.char_indices() {
                if is_punctuation(c) {
                    self.word_pieces(&word[start..i], emit);
                    let end = i + c.len_utf8();
                    self.word_pieces(&word[i..end], emit);
                    start = end;
                }
            }
            self.word_pieces(&word[start..], emit);
        }
    }

    /// BertNormalizer: clean, pad CJK ideographs, strip accents and lower-case.
    pub fn normalize(&self, text: &str) -> String {
        let mut out = String::with_capacity(text.len() + 8);
        for c in text.chars() {
            if c == '\0' || c == '\u{fffd}' || is_control(c) {
                continue;
            }
            if is_whitespace(c) {
                out.push(' ');
            } else if is_cjk(c) {
                out.push(' ');
                out.push(c);
                out.push(' ');
            } else {
                out.push(c);
            }
        }
        if !self.lowercase {
            return out;
        }
        if out.is_ascii() {
            out.make_ascii_lowercase();
            return out;
        }
        out.nfd()
            .filter(|&c| get_general_category(c) != GeneralCategory::NonspacingMark)
            .flat_map(char::to_lowercase)
            .collect()
    }

    /// Greedy longest-match-first WordPiece of one word.
    fn word_pieces(&self, word: &str, emit: &mut dyn FnMut(&str, u32)) {
        if word.is_empty() {
            return;
        }
        if word.chars().count() > MAX_WORD_CHARS {
            emit("[UNK]", self.unk);
            return;
        }
        let mut pieces: Vec<(usize, usize, u32)> = Vec::new();
        let mut start = 0;
        let mut candidate = String::with_capacity(word.len() + 2);
        while start < word.len() {
            let mut end = word.len();
            let mut found = None;
            while end > start {
                candidate.clear();
                if start > 0 {
                    candidate.push_str("##");
                }
                candidate.push_str(&word[start..end]);
                if let Some(&id) = self.vocab.get(candidate.as_str()) {
                    found = Some(id);
                    break;
                }
                // One character back.
                end = word[..end]
                    .char_indices()
                    .next_back()
                    .map_or(start, |(i, _)| i);
            }
            match found {
                Some(id) => {
                    pieces.push((start, end, id));
                    start = end;
                }
                None => {
                    emit("[UNK]", self.unk);
                    return;
                }
            }
        }
        let mut text = String::new();
        for (s, e, id) in pieces {
            text.clear();
            if s > 0 {
                text.push_str("##");
            }
            text.push_str(&word[s..e]);
            emit(&text, id);
        }
    }
}

/// Tab, newline and carriage return, and Rust's (Unicode's) White_Space characters.
fn is_whitespace(c: char) -> bool {
    matches!(c, '\t' | '\n' | '\r') || c.is_whitespace()
}

/// The "other" categories (Cc, Cf, Cn, Co, Cs) except tab, newline and carriage return.
fn is_control(c: char) -> bool {
    if matches!(c, '\t' | '\n' | '\r') {
        return false;
    }
    if c.is_ascii() {
        return c.is_ascii_control();
    }
    matches!(
        get_general_category(c),
        GeneralCategory::Control
            | GeneralCategory::Format
            | GeneralCategory::Unassigned
            | GeneralCategory::PrivateUse
            | GeneralCategory::Surrogate
    )
}

/// ASCII punctuation (symbols such as `$`, `+`, `<` included, as BERT counts them) and the
/// Unicode punctuation categories.
fn is_punctuation(c: char) -> bool {
    if c.is_ascii() {
        return c.is_ascii_punctuation();
    }
    matches!(
        get_general_category(c),
        GeneralCategory::ConnectorPunctuation
            | GeneralCategory::DashPunctuation
            | GeneralCategory::ClosePunctuation
            | GeneralCategory::FinalPunctuation
            | GeneralCategory::InitialPunctuation
            | GeneralCategory::OtherPunctuation
            | GeneralCategory::OpenPunctuation
    )
}

/// The CJK ideograph blocks BERT pads with spaces.
fn is_cjk(c: char) -> bool {
    matches!(
        c as u32,
        0x4E00..=0x9FFF
            | 0x3400..=0x4DBF
            | 0x20000..=0x2A6DF
            | 0x2A700..=0x2B73F
            | 0x2B740..=0x2B81F
            | 0x2B820..=0x2CEAF
            | 0xF900..=0xFAFF
            | 0x2F800..=0x2FA1F
    )
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn toy() -> Tokenizer {
        let vocab = [
            "[PAD]", "[UNK]", "[CLS]", "[SEP]", "[MASK]", "slow", "down", "##s", "un", "##aff",
            "##able", ",", ".", "cafe", "!", "a", "##b", "车",
        ]
        .join("\n");
        Tokenizer::from_vocab(&vocab, true, 8).unwrap()
    }

    #[test]
    fn wordpiece_cuts_the_longest_pieces_and_unknown_words_become_unk() {
        let t = toy();
        assert_eq!(
            t.tokenize("Unaffable downs"),
            ["un", "##aff", "##able", "down", "##s"]
        );
        assert_eq!(t.tokenize("unxable"), ["[UNK]"]);
        assert_eq!(t.tokenize("Slow,down!"), ["slow", ",", "down", "!"]);
        assert_eq!(t.tokenize(&"a".repeat(101)), ["[UNK]"]);
    }

    #[test]
    fn normalisation_strips_accents_controls_and_pads_cjk() {
        let t = toy();
        assert_eq!(t.normalize("Café\u{0}\u{200b}\tX车"), "cafe x 车 ");
        assert_eq!(t.tokenize("CAFÉ 车"), ["cafe", "车"]);
    }

    #[test]
    fn specials_in_the_text_keep_their_ids_and_encode_truncates() {
        let t = toy();
        assert_eq!(t.encode("slow[MASK]down"), [2, 5, 4, 6, 3]);
        assert_eq!(t.encode(""), [2, 3]);
        let long = t.encode("slow slow slow slow slow slow slow slow slow");
        assert_eq!(long.len(), 8);
        assert_eq!((long[0], long[7]), (2, 3));
    }
}
