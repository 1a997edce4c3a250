//! The text encodings of Zemax files: UTF-16 in either byte order with or without a byte order
//! mark (Zemax and Thorlabs write UTF-16 LE with a BOM), UTF-8 with or without one, and
//! ISO-8859-1 (older vendor files, with `Ø` as the single byte D8).

/// The decoded text, or why the bytes cannot be text.
pub fn decode(bytes: &[u8]) -> Result<String, String> {
    if let Some(rest) = bytes.strip_prefix(&[0xFF, 0xFE]) {
        return utf16(rest, u16::from_le_bytes);
    }
    if let Some(rest) = bytes.strip_prefix(&[0xFE, 0xFF]) {
        return utf16(rest, u16::from_be_bytes);
    }
    if let Some(rest) = bytes.strip_prefix(&[0xEF, 0xBB, 0xBF]) {
        return String::from_utf8(rest.to_vec())
            .map_err(|e| format!("not UTF-8 text after its UTF-8 byte order mark ({e})"));
    }
    // Without a BOM, ASCII text in UTF-16 has a NUL in every other byte: in the odd bytes for
    // little-endian, the even ones for big-endian.
    let head = &bytes[..bytes.len().min(400)];
    if head.len() >= 4 {
        let even_nul = head.iter().step_by(2).filter(|&&b| b == 0).count();
        let odd_nul = head.iter().skip(1).step_by(2).filter(|&&b| b == 0).count();
        let quarter = head.len() / 4;
        if odd_nul > quarter && even_nul == 0 {
            return utf16(bytes, u16::from_le_bytes);
        }
        if even_nul > quarter && odd_nul == 0 {
            return utf16(bytes, u16::from_be_bytes);
        }
    }
    match String::from_utf8(bytes.to_vec()) {
        Ok(s) => Ok(s),
        // ISO-8859-1 maps every byte to the code point of the same value.
        Err(_) => Ok(bytes.iter().map(|&b| b as char).collect()),
    }
}

fn utf16(bytes: &[u8], unit: fn([u8; 2]) -> u16) -> Result<String, String> {
    if !bytes.len().is_multiple_of(2) {
        return Err(format!(
            "UTF-16 text of odd length ({} bytes after the byte order mark, if any): the file is \
             truncated or not UTF-16",
            bytes.len()
        ));
    }
    let units: Vec<u16> = bytes.chunks_exact(2).map(|c| unit([c[0], c[1]])).collect();
    String::from_utf16(&units).map_err(|e| format!("not valid UTF-16 text ({e})"))
}

#[cfg(test)]
mod tests {
    use super::decode;

    #[test]
    fn every_encoding_decodes_to_the_same_text() {
        let text = "NAME Ø25.4 mm\r\nMODE SEQ\r\n";
        let le: Vec<u8> = text.encode_utf16().flat_map(|u| u.to_le_bytes()).collect();
        let be: Vec<u8> = text.encode_utf16().flat_map(|u| u.to_be_bytes()).collect();
        let latin: Vec<u8> = text.chars().map(|c| c as u32 as u8).collect();
        for bytes in [
            [&[0xFF, 0xFE][..], &le].concat(),
            [&[0xFE, 0xFF][..], &be].concat(),
            le.clone(),
            be.clone(),
            text.as_bytes().to_vec(),
            [&[0xEF, 0xBB, 0xBF][..], text.as_bytes()].concat(),
            latin,
        ] {
            assert_eq!(decode(&bytes).unwrap(), text);
        }
        let odd = [&[0xFF, 0xFE][..], &le, &[0x41]].concat();
        assert!(decode(&odd).unwrap_err().contains("odd length"));
    }
}
