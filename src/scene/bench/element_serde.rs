//! A bench file writes each element as a struct variant of `ElementSpec`
//! (`Lens(name: "collimator", …)`), while each variant of the type holds a struct of its own
//! (`ElementSpec::Lens(LensSpec)`), so that each builder takes its own fields. Serde's derive
//! would read and write such a variant as a newtype variant (`Lens((name: …))` in RON), so
//! `ElementSpec` is read and written here by hand: each struct's derived code runs through the
//! format's struct-variant access, exactly the calls (names, fields, errors) the derived
//! struct variants made.

use std::fmt;

use serde::de::{self, Deserialize, Deserializer, EnumAccess, VariantAccess, Visitor};
use serde::ser::{
    self, Impossible, Serialize, SerializeStruct, SerializeStructVariant, Serializer,
};

use super::schema::{
    ApertureSpec, BaffleSpec, ChartSpec, ElementSpec, FilterSpec, LensSpec, LensSystemSpec,
    MirrorSpec, TubeSpec,
};

/// The variant names, in declaration order (their indices).
const VARIANTS: &[&str] = &[
    "Lens",
    "Filter",
    "Aperture",
    "Tube",
    "Baffle",
    "Mirror",
    "Chart",
    "LensSystem",
];

/// A variant's tag, read from its name (or index) as serde's derive reads it.
#[derive(serde::Deserialize)]
#[serde(variant_identifier)]
enum Kind {
    Lens,
    Filter,
    Aperture,
    Tube,
    Baffle,
    Mirror,
    Chart,
    LensSystem,
}

impl<'de> Deserialize<'de> for ElementSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<ElementSpec, D::Error> {
        d.deserialize_enum("ElementSpec", VARIANTS, ElementVisitor)
    }
}

struct ElementVisitor;

impl<'de> Visitor<'de> for ElementVisitor {
    type Value = ElementSpec;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("enum ElementSpec")
    }

    fn visit_enum<A: EnumAccess<'de>>(self, data: A) -> Result<ElementSpec, A::Error> {
        let (kind, v) = data.variant::<Kind>()?;
        let v = StructVariant(v);
        Ok(match kind {
            Kind::Lens => ElementSpec::Lens(LensSpec::deserialize(v)?),
            Kind::Filter => ElementSpec::Filter(FilterSpec::deserialize(v)?),
            Kind::Aperture => ElementSpec::Aperture(ApertureSpec::deserialize(v)?),
            Kind::Tube => ElementSpec::Tube(TubeSpec::deserialize(v)?),
            Kind::Baffle => ElementSpec::Baffle(BaffleSpec::deserialize(v)?),
            Kind::Mirror => ElementSpec::Mirror(MirrorSpec::deserialize(v)?),
            Kind::Chart => ElementSpec::Chart(ChartSpec::deserialize(v)?),
            Kind::LensSystem => ElementSpec::LensSystem(LensSystemSpec::deserialize(v)?),
        })
    }
}

/// A variant's content as a deserializer of one struct: a derived struct's
/// `deserialize_struct(name, fields, visitor)` becomes the variant's
/// `struct_variant(fields, visitor)`.
struct StructVariant<A>(A);

impl<'de, A: VariantAccess<'de>> Deserializer<'de> for StructVariant<A> {
    type Error = A::Error;

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, A::Error> {
        self.0.struct_variant(fields, visitor)
    }

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, A::Error> {
        Err(de::Error::custom("a bench element is read as a struct"))
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
        option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
        ignored_any
    }
}

impl Serialize for ElementSpec {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let variant = |index: u32| AsStructVariant {
            s,
            index,
            variant: VARIANTS[index as usize],
        };
        match self {
            ElementSpec::Lens(x) => x.serialize(variant(0)),
            ElementSpec::Filter(x) => x.serialize(variant(1)),
            ElementSpec::Aperture(x) => x.serialize(variant(2)),
            ElementSpec::Tube(x) => x.serialize(variant(3)),
            ElementSpec::Baffle(x) => x.serialize(variant(4)),
            ElementSpec::Mirror(x) => x.serialize(variant(5)),
            ElementSpec::Chart(x) => x.serialize(variant(6)),
            ElementSpec::LensSystem(x) => x.serialize(variant(7)),
        }
    }
}

/// A serializer of one struct that writes it as the struct variant `variant` of `ElementSpec`.
struct AsStructVariant<S> {
    s: S,
    index: u32,
    variant: &'static str,
}

/// The fields of a struct written as a struct variant's.
struct VariantFields<V>(V);

impl<V: SerializeStructVariant> SerializeStruct for VariantFields<V> {
    type Ok = V::Ok;
    type Error = V::Error;

    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), V::Error> {
        self.0.serialize_field(key, value)
    }

    fn skip_field(&mut self, key: &'static str) -> Result<(), V::Error> {
        self.0.skip_field(key)
    }

    fn end(self) -> Result<V::Ok, V::Error> {
        self.0.end()
    }
}

fn not_a_struct<E: ser::Error>() -> E {
    E::custom("a bench element is written from a struct")
}

/// The serializer methods a struct never calls.
macro_rules! refuse {
    ($($f:ident($($t:ty),*) -> $r:ty;)*) => {
        $(fn $f(self, $(_: $t),*) -> Result<$r, S::Error> { Err(not_a_struct()) })*
    };
}

impl<S: Serializer> Serializer for AsStructVariant<S> {
    type Ok = S::Ok;
    type Error = S::Error;
    type SerializeSeq = Impossible<S::Ok, S::Error>;
    type SerializeTuple = Impossible<S::Ok, S::Error>;
    type SerializeTupleStruct = Impossible<S::Ok, S::Error>;
    type SerializeTupleVariant = Impossible<S::Ok, S::Error>;
    type SerializeMap = Impossible<S::Ok, S::Error>;
    type SerializeStruct = VariantFields<S::SerializeStructVariant>;
    type SerializeStructVariant = Impossible<S::Ok, S::Error>;

    fn serialize_struct(
        self,
        _name: &'static str,
        len: usize,
    ) -> Result<Self::SerializeStruct, S::Error> {
        self.s
            .serialize_struct_variant("ElementSpec", self.index, self.variant, len)
            .map(VariantFields)
    }

    refuse! {
        serialize_bool(bool) -> S::Ok;
        serialize_i8(i8) -> S::Ok;
        serialize_i16(i16) -> S::Ok;
        serialize_i32(i32) -> S::Ok;
        serialize_i64(i64) -> S::Ok;
        serialize_u8(u8) -> S::Ok;
        serialize_u16(u16) -> S::Ok;
        serialize_u32(u32) -> S::Ok;
        serialize_u64(u64) -> S::Ok;
        serialize_f32(f32) -> S::Ok;
        serialize_f64(f64) -> S::Ok;
        serialize_char(char) -> S::Ok;
        serialize_str(&str) -> S::Ok;
        serialize_bytes(&[u8]) -> S::Ok;
        serialize_none() -> S::Ok;
        serialize_unit() -> S::Ok;
        serialize_unit_struct(&'static str) -> S::Ok;
        serialize_unit_variant(&'static str, u32, &'static str) -> S::Ok;
        serialize_seq(Option<usize>) -> Self::SerializeSeq;
        serialize_tuple(usize) -> Self::SerializeTuple;
        serialize_tuple_struct(&'static str, usize) -> Self::SerializeTupleStruct;
        serialize_tuple_variant(&'static str, u32, &'static str, usize) -> Self::SerializeTupleVariant;
        serialize_map(Option<usize>) -> Self::SerializeMap;
        serialize_struct_variant(&'static str, u32, &'static str, usize) -> Self::SerializeStructVariant;
    }

    fn serialize_some<T: Serialize + ?Sized>(self, _: &T) -> Result<S::Ok, S::Error> {
        Err(not_a_struct())
    }

    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: &T,
    ) -> Result<S::Ok, S::Error> {
        Err(not_a_struct())
    }

    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> Result<S::Ok, S::Error> {
        Err(not_a_struct())
    }
}
