//! The library's names for what the command line takes as flags. The library never spells a
//! flag (a Python caller passed none): it names its own field (`vary`, `free`, `merge`) and,
//! in a message, an option in backquotes (`` `resume` ``). An input error that reaches the
//! command line is shown with the flag instead ([`relocate`]), so `--vary a=1:2:x` reads
//! "field `--vary`: …". The test `layering::library_errors_name_no_flags` keeps flags out of
//! the library's error messages.

/// (the library's name, the flag), for the fields and options of the jobs that the command
/// line sets from a flag. Only names that no input file has as a top-level field: an error of
/// a bench, experiment, tolerance or dataset file names its field by its full path.
pub const FLAGS: &[(&str, &str)] = &[
    ("vary", "--vary"),
    ("set", "--set"),
    ("dmd_model", "--dmd-model"),
    ("element", "--element"),
    ("limit", "--limit"),
    ("free", "--free"),
    ("weight", "--weight"),
    ("min_fraction", "--min-fraction"),
    ("offset_weight", "--offset-weight"),
    ("repeats", "--repeats"),
    ("merge", "--merge"),
    ("resume", "--resume"),
    ("shard", "--shard"),
    ("out", "--out"),
    ("data_range", "--data-range"),
    ("wavelength_nm", "--wavelength-nm"),
    ("footprint_rays", "--footprint-rays"),
    ("target_yield", "--target-yield"),
    ("confidence", "--confidence"),
    ("irradiance_at", "--irradiance-at"),
    ("irradiance_rays", "--irradiance-rays"),
];

/// Options named in messages only (`quality` is also a tolerance file's section, whose errors
/// keep their field).
const IN_MESSAGES: &[(&str, &str)] = &[("quality", "--quality"), ("allow_large", "--allow-large")];

/// An input error as the command line shows it: its field, when it is one of [`FLAGS`], and
/// each of their names in backquotes in its message, become the flag. Other errors are
/// returned as they are.
pub fn relocate(mut e: crate::Error) -> crate::Error {
    if let crate::Error::Input { location, message } = &mut e {
        if let Some(field) = &location.field
            && let Some((_, flag)) = FLAGS.iter().find(|(name, _)| name == field)
        {
            location.field = Some(flag.to_string());
        }
        for (name, flag) in FLAGS.iter().chain(IN_MESSAGES) {
            let quoted = format!("`{name}`");
            if message.contains(&quoted) {
                *message = message.replace(&quoted, flag);
            }
        }
    }
    e
}

/// [`relocate`] on the library error inside a command's error, if there is one.
pub fn relocate_any(mut e: anyhow::Error) -> anyhow::Error {
    if let Some(inner) = e.downcast_mut::<crate::Error>() {
        let taken = std::mem::replace(inner, crate::Error::Numerical(String::new()));
        *inner = relocate(taken);
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_and_quoted_options_become_flags() {
        let e = relocate(crate::Error::field(
            "vary",
            "`a=1`: expected PATH=START:STOP:N",
        ));
        assert_eq!(
            e.to_string(),
            "field `--vary`: `a=1`: expected PATH=START:STOP:N"
        );
        let e = relocate(
            crate::Error::input("the folder is not empty: continue it with `resume`")
                .in_file(std::path::Path::new("out")),
        );
        assert_eq!(
            e.to_string(),
            "out: the folder is not empty: continue it with --resume"
        );
        // A file's field keeps its name; its full path is never a bare option name.
        let e = relocate(crate::Error::field("run.rays", "too few"));
        assert!(e.to_string().contains("field `run.rays`"), "{e}");
        let any = relocate_any(anyhow::Error::new(crate::Error::field(
            "merge",
            "no folders",
        )));
        assert!(any.to_string().contains("field `--merge`"), "{any}");
    }

    /// Every library name is spelt as its flag would be (lower case, `_` for `-`).
    #[test]
    fn names_match_their_flags() {
        for (name, flag) in FLAGS.iter().chain(IN_MESSAGES) {
            assert_eq!(format!("--{}", name.replace('_', "-")), *flag);
        }
    }
}
