//! Axis labels for bench variables: a variable's path (`ELEMENT.FIELD[.COMPONENT]`, as
//! `scene::variables` names it) written as words with the unit its field's suffix states, so
//! that `detectors.minus.decenter_mm.x` reads "− diode decentre x (mm)" on a figure.

/// Unit suffixes of the bench file's field names and how a figure writes them, the longer
/// suffixes first (`_v_per_a` before `_a`).
const UNITS: [(&str, &str); 17] = [
    ("_v_per_a", "V/A"),
    ("_a_per_w", "A/W"),
    ("_percent", "%"),
    ("_deg", "°"),
    ("_rad", "rad"),
    ("_mm", "mm"),
    ("_um", "µm"),
    ("_nm", "nm"),
    ("_hz", "Hz"),
    ("_us", "µs"),
    ("_ms", "ms"),
    ("_ohm", "Ω"),
    ("_s", "s"),
    ("_v", "V"),
    ("_a", "A"),
    ("_w", "W"),
    ("_k", "K"),
];

/// The bench file's sections and the name a figure gives them.
const SECTIONS: [(&str, &str); 6] = [
    ("dmd", "DMD"),
    ("lamp", "lamp"),
    ("electronics", "electronics"),
    ("illumination", "illumination"),
    ("run", "run"),
    ("detectors", "detectors"),
];

/// A field name as words (underscores as spaces, in British spelling, as the guide writes) and
/// the unit its suffix states.
fn field_words(field: &str) -> (String, Option<&'static str>) {
    let (stem, unit) = UNITS
        .iter()
        .find_map(|(suffix, unit)| {
            field
                .strip_suffix(suffix)
                .filter(|s| !s.is_empty())
                .map(|s| (s, Some(*unit)))
        })
        .unwrap_or((field, None));
    let words = stem
        .replace('_', " ")
        .replace("center", "centre")
        .replace("decenter", "decentre");
    (words, unit)
}

/// The axis label of a bench variable: its part, field and component as words, then the unit of
/// the field's suffix in parentheses ("− diode decentre x (mm)", "DMD tilt (°)"); a path with
/// no unit suffix is written as words alone.
pub fn variable_label(path: &str) -> String {
    let parts: Vec<&str> = path.split('.').collect();
    let (part, rest) = match parts.as_slice() {
        // A top-level field of the bench file (`band_nm`).
        [field] => {
            let (w, u) = field_words(field);
            return u.map_or_else(|| w.clone(), |u| format!("{w} ({u})"));
        }
        ["detectors", "plus", rest @ ..] => ("+ diode".to_string(), rest),
        ["detectors", "minus", rest @ ..] => ("− diode".to_string(), rest),
        [first, rest @ ..] => (
            SECTIONS
                .iter()
                .find(|(s, _)| s == first)
                .map_or_else(|| (*first).to_string(), |(_, name)| (*name).to_string()),
            rest,
        ),
        [] => return String::new(),
    };
    let mut words = vec![part];
    let mut unit = None;
    for p in rest {
        if unit.is_none() {
            let (w, u) = field_words(p);
            words.push(w);
            unit = u;
        } else {
            words.push((*p).to_string());
        }
    }
    let text = words.join(" ");
    match unit {
        Some(u) => format!("{text} ({u})"),
        None => text,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_carry_the_unit_of_the_suffix() {
        for (path, label) in [
            ("detectors.minus.decenter_mm.x", "− diode decentre x (mm)"),
            ("detectors.plus.tilt_deg.y", "+ diode tilt y (°)"),
            ("dmd.tilt_deg", "DMD tilt (°)"),
            ("illumination.turn_deg", "illumination turn (°)"),
            ("lens_1.position_mm.z", "lens_1 position z (mm)"),
            (
                "electronics.gain_50_ohm_v_per_a",
                "electronics gain 50 ohm (V/A)",
            ),
            ("lamp.temperature_k", "lamp temperature (K)"),
            ("band_nm", "band (nm)"),
            ("max_interactions", "max interactions"),
            ("dmd.pitch_um", "DMD pitch (µm)"),
        ] {
            assert_eq!(variable_label(path), label, "{path}");
        }
    }
}
