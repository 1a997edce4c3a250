//! `spibench completions SHELL` (clap_complete) and `spibench man DIR` (clap_mangen): the
//! command line described for shells and for `man`, generated from the same definitions that
//! parse it, so they cannot drift apart.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Args;
use clap_complete::Shell;

use crate::report::output::OutputDir;

#[derive(Debug, Clone, Args)]
pub struct CompletionsArgs {
    /// The shell: bash, zsh, fish, elvish or powershell.
    pub shell: Shell,
}

#[derive(Debug, Clone, Args)]
pub struct ManArgs {
    /// Folder for `spibench.1` and `spibench-COMMAND.1`.
    #[arg(long, default_value = "out/man")]
    pub out: PathBuf,
}

/// Prints the completion script for one shell to stdout.
pub fn completions(a: &CompletionsArgs, mut cmd: clap::Command) -> Result<()> {
    clap_complete::generate(a.shell, &mut cmd, "spibench", &mut std::io::stdout());
    Ok(())
}

/// Writes the man pages of spibench and of each subcommand.
pub fn man(a: &ManArgs, cmd: clap::Command) -> Result<()> {
    let out = OutputDir::create(&a.out)?;
    let mut pages = vec![("spibench".to_string(), cmd.clone())];
    for sub in cmd.get_subcommands() {
        pages.push((format!("spibench-{}", sub.get_name()), sub.clone()));
    }
    for (name, page) in &pages {
        let file = format!("{name}.1");
        let mut text = Vec::new();
        clap_mangen::Man::new(page.clone())
            .title(name.to_uppercase())
            .render(&mut text)
            .with_context(|| format!("rendering {file}"))?;
        std::fs::write(out.path(&file), text).with_context(|| format!("writing {file}"))?;
    }
    let dir = out.commit()?;
    println!("wrote {} ({} man pages)", dir.display(), pages.len());
    Ok(())
}
