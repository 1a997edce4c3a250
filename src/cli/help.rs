//! Help texts that quote the code's own tables, so that a count or a list in `--help` cannot
//! go stale when a table grows (the schemes: `acquisition::Scheme::all`), and the check that
//! no help text states another count of schemes.

use std::sync::OnceLock;

use crate::acquisition::Scheme;

/// "the 7 acquisition schemes", from [`Scheme::all`].
pub fn schemes_phrase() -> String {
    format!("the {} acquisition schemes", Scheme::all().len())
}

/// A help text made once and kept for the program's life (clap takes `&'static str`).
fn once(cell: &'static OnceLock<String>, make: impl FnOnce() -> String) -> &'static str {
    cell.get_or_init(make).as_str()
}

/// `spibench run`'s one-line description.
pub fn run_about() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    once(&TEXT, || {
        format!(
            "The whole traced experiment: trace, detector electronics in time, {}, \
             reconstruction and scores (default: the paper's bench, built in)",
            schemes_phrase()
        )
    })
}

/// `sweep --quality`'s help.
pub fn sweep_quality_help() -> &'static str {
    static TEXT: OnceLock<String> = OnceLock::new();
    once(&TEXT, || {
        format!(
            "Run the whole pipeline (detector, {}, reconstruction, scores) on every point, \
             with the bench's `run` settings",
            schemes_phrase()
        )
    })
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    use super::*;

    /// Number words a help text might count schemes with.
    const WORDS: [&str; 13] = [
        "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
        "eleven", "twelve",
    ];

    /// Every count of schemes stated in a help text: the word or number before "schemes" (or
    /// "acquisition schemes").
    fn scheme_counts(text: &str) -> Vec<(usize, String)> {
        let words: Vec<&str> = text.split_whitespace().collect();
        let mut out = Vec::new();
        for (i, w) in words.iter().enumerate() {
            if !w
                .trim_matches(|c: char| !c.is_alphanumeric())
                .eq_ignore_ascii_case("schemes")
            {
                continue;
            }
            let mut k = i;
            while k > 0 {
                k -= 1;
                // Punctuation around a word, not a sign before a number ("±1 schemes").
                let prev = words[k]
                    .trim_matches(|c: char| "()[],.;:\"'`".contains(c))
                    .to_lowercase();
                if prev == "acquisition" || prev == "fairer" || prev == "other" {
                    continue;
                }
                if let Some(n) = WORDS.iter().position(|x| *x == prev) {
                    out.push((n, words[k..=i].join(" ")));
                } else if let Ok(n) = prev.parse() {
                    out.push((n, words[k..=i].join(" ")));
                }
                break;
            }
        }
        out
    }

    fn all_help(cmd: &mut clap::Command, path: &str, out: &mut Vec<(String, String)>) {
        out.push((path.to_string(), cmd.render_long_help().to_string()));
        let names: Vec<String> = cmd
            .get_subcommands()
            .map(|s| s.get_name().to_string())
            .collect();
        for name in names {
            if let Some(sub) = cmd.find_subcommand_mut(&name) {
                all_help(sub, &format!("{path} {name}"), out);
            }
        }
    }

    /// No help text of any command states a count of schemes other than the table's, and the
    /// texts that count them say the table's count.
    #[test]
    fn help_texts_count_the_schemes_the_code_has() {
        let n = Scheme::all().len();
        let mut helps = Vec::new();
        let mut cmd = crate::cli::Cli::command();
        cmd.build();
        all_help(&mut cmd, "spibench", &mut helps);
        let mut counted = 0;
        for (path, text) in &helps {
            for (k, phrase) in scheme_counts(text) {
                assert_eq!(
                    k, n,
                    "`{path} --help` says {phrase:?}; the code has {n} schemes"
                );
                counted += 1;
            }
        }
        assert!(
            counted >= 2,
            "the run and sweep help texts count the schemes"
        );
        let top = &helps[0].1;
        assert!(top.contains(&schemes_phrase()), "{top}");
        assert_eq!(
            scheme_counts("the four schemes and 3 acquisition schemes"),
            vec![
                (4, "four schemes".to_string()),
                (3, "3 acquisition schemes".to_string())
            ]
        );
    }
}
