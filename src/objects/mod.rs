//! Objects to image: the modified Shepp–Logan phantom, the 1951 USAF chart, and image files.

pub mod usaf;
