//! A row-major grid of f64 values: objects, reconstructions, per-unit maps.

use crate::error::{Error, Result};

#[derive(Debug, Clone, PartialEq)]
pub struct Raster {
    pub width: usize,
    pub height: usize,
    /// Row-major: `data[row * width + column]`.
    pub data: Vec<f64>,
}

impl Raster {
    pub fn new(width: usize, height: usize, data: Vec<f64>) -> Result<Self> {
        if width == 0 || height == 0 {
            return Err(Error::input(format!(
                "a {width}×{height} image has no pixels"
            )));
        }
        if data.len() != width * height {
            return Err(Error::input(format!(
                "{} values cannot form a {width}×{height} image ({} expected)",
                data.len(),
                width * height
            )));
        }
        Ok(Raster {
            width,
            height,
            data,
        })
    }

    pub fn zeros(width: usize, height: usize) -> Self {
        Raster {
            width,
            height,
            data: vec![0.0; width * height],
        }
    }

    pub fn from_fn(width: usize, height: usize, f: impl Fn(usize, usize) -> f64) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for r in 0..height {
            for c in 0..width {
                data.push(f(r, c));
            }
        }
        Raster {
            width,
            height,
            data,
        }
    }

    pub fn len(&self) -> usize {
        self.data.len()
    }

    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    #[inline]
    pub fn get(&self, row: usize, col: usize) -> f64 {
        self.data[row * self.width + col]
    }

    #[inline]
    pub fn set(&mut self, row: usize, col: usize, v: f64) {
        self.data[row * self.width + col] = v;
    }

    pub fn min(&self) -> f64 {
        self.data.iter().copied().fold(f64::INFINITY, f64::min)
    }

    pub fn max(&self) -> f64 {
        self.data.iter().copied().fold(f64::NEG_INFINITY, f64::max)
    }

    pub fn sum(&self) -> f64 {
        self.data.iter().sum()
    }

    pub fn map(&self, f: impl Fn(f64) -> f64) -> Raster {
        Raster {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(|&v| f(v)).collect(),
        }
    }
}
