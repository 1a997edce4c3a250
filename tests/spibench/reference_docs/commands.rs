//! The commands page: every command of `spibench::cli::command()` (the clap definitions that
//! parse the command line), with its usage, arguments, defaults, accepted values and help.

use clap::{Arg, ArgAction, Command};

use super::formats::GENERATED;

/// One cell of Markdown: one line, pipes escaped.
fn cell(s: &str) -> String {
    s.split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
        .replace('|', "\\|")
}

/// How an argument is written: `--rays <N>`, `-q, --quiet`, `<BENCH>`.
fn spelling(a: &Arg) -> String {
    let takes_value = matches!(a.get_action(), ArgAction::Set | ArgAction::Append);
    let value = a
        .get_value_names()
        .map(|v| {
            v.iter()
                .map(|n| format!("<{n}>"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .unwrap_or_else(|| format!("<{}>", a.get_id().as_str().to_uppercase()));
    if a.is_positional() {
        return value;
    }
    let mut names = Vec::new();
    if let Some(s) = a.get_short() {
        names.push(format!("-{s}"));
    }
    if let Some(l) = a.get_long() {
        names.push(format!("--{l}"));
    }
    let mut s = names.join(", ");
    if takes_value {
        s.push(' ');
        s.push_str(&value);
    }
    s
}

fn args_table(args: &[&Arg]) -> String {
    let mut out = String::from("| argument | default | help |\n|---|---|---|\n");
    for a in args {
        // A switch's `false` is no default worth a column.
        let switch = matches!(a.get_action(), ArgAction::SetTrue | ArgAction::SetFalse);
        let default: Vec<String> = a
            .get_default_values()
            .iter()
            .filter(|_| !switch)
            .collect::<Vec<_>>()
            .iter()
            .map(|v| format!("`{}`", v.to_string_lossy()))
            .collect();
        let mut help = a
            .get_long_help()
            .or_else(|| a.get_help())
            .map(|h| h.to_string())
            .unwrap_or_default();
        let values: Vec<String> = a
            .get_possible_values()
            .iter()
            .filter(|v| !v.is_hide_set())
            .map(|v| match v.get_help() {
                Some(h) => format!("`{}` ({})", v.get_name(), cell(&h.to_string())),
                None => format!("`{}`", v.get_name()),
            })
            .collect();
        let mut extra = Vec::new();
        if !values.is_empty() && matches!(a.get_action(), ArgAction::Set | ArgAction::Append) {
            extra.push(format!("Values: {}.", values.join(", ")));
        }
        if a.is_required_set() {
            extra.push("Required.".to_string());
        }
        if matches!(a.get_action(), ArgAction::Append) {
            extra.push("May be repeated.".to_string());
        }
        if !extra.is_empty() {
            let h = help.trim_end();
            help = if h.is_empty() || h.ends_with(['.', ')', ':']) {
                format!("{h} {}", extra.join(" "))
            } else {
                format!("{h}. {}", extra.join(" "))
            };
        }
        out.push_str(&format!(
            "| `{}` | {} | {} |\n",
            spelling(a),
            default.join(", "),
            cell(&help)
        ));
    }
    out.push('\n');
    out
}

fn about(c: &Command) -> String {
    c.get_long_about()
        .or_else(|| c.get_about())
        .map(|s| s.to_string())
        .unwrap_or_default()
}

/// The Markdown of the commands page.
pub fn page(cmd: &Command) -> String {
    let mut cmd = cmd.clone().term_width(100);
    cmd.build();
    let mut out = String::from("# Commands\n\n");
    out.push_str(GENERATED);
    out.push_str(&format!("{}\n\n", about(&cmd).trim()));
    out.push_str(
        "Every command below also takes the global arguments of the last section. \
         `spibench COMMAND --help` prints the same text; `spibench man DIR` writes it as man \
         pages.\n\n| command | what it does |\n|---|---|\n",
    );
    let subs: Vec<&Command> = cmd
        .get_subcommands()
        .filter(|s| !s.is_hide_set() && s.get_name() != "help")
        .collect();
    for s in &subs {
        let first = cell(&about(s));
        out.push_str(&format!(
            "| [`{}`](#{}) | {first} |\n",
            s.get_name(),
            format_args!("spibench-{}", s.get_name())
        ));
    }
    out.push('\n');
    for s in &subs {
        out.push_str(&format!("## `spibench {}`\n\n", s.get_name()));
        out.push_str(&format!("{}\n\n", about(s).trim()));
        let mut s = (*s).clone();
        let usage = s.render_usage().to_string();
        let usage = usage.trim_start_matches("Usage: ").trim();
        out.push_str(&format!("```text\n{usage}\n```\n\n"));
        let args: Vec<&Arg> = s
            .get_arguments()
            .filter(|a| !a.is_hide_set() && !a.is_global_set())
            .filter(|a| !matches!(a.get_id().as_str(), "help" | "version"))
            .collect();
        if !args.is_empty() {
            out.push_str(&args_table(&args));
        }
    }
    out.push_str("## Global arguments\n\n");
    let globals: Vec<&Arg> = cmd
        .get_arguments()
        .filter(|a| !a.is_hide_set())
        .filter(|a| !matches!(a.get_id().as_str(), "help" | "version"))
        .collect();
    out.push_str(&args_table(&globals));
    out.push_str("`-h, --help` prints a command's help, `-V, --version` the version.\n");
    out
}

/// Commands without an about text and arguments without a help text.
pub fn undocumented(cmd: &Command) -> Vec<String> {
    let mut cmd = cmd.clone();
    cmd.build();
    let mut out = Vec::new();
    let visible = |a: &&Arg| !a.is_hide_set() && !matches!(a.get_id().as_str(), "help" | "version");
    for a in cmd.get_arguments().filter(visible) {
        if a.get_help().is_none() {
            out.push(format!(
                "src/cli: `spibench {}` has no help text",
                spelling(a)
            ));
        }
    }
    for s in cmd
        .get_subcommands()
        .filter(|s| !s.is_hide_set() && s.get_name() != "help")
    {
        if s.get_about().is_none() {
            out.push(format!(
                "src/cli: `spibench {}` has no about text",
                s.get_name()
            ));
        }
        for a in s
            .get_arguments()
            .filter(visible)
            .filter(|a| !a.is_global_set())
        {
            if a.get_help().is_none() {
                out.push(format!(
                    "src/cli: `spibench {} {}` has no help text",
                    s.get_name(),
                    spelling(a)
                ));
            }
        }
    }
    out
}
