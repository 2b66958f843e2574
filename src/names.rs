//! The name of an enum value is its serde spelling, the one the scene files, the JSON reports
//! and the CLI already use: [`variant_name`] reads it from the derived `Serialize` (no second
//! list of names to keep in step), [`from_name`] parses it through the derived
//! `Deserialize`.

use serde::de::value::{Error as ValueError, StrDeserializer};
use serde::de::DeserializeOwned;
use serde::ser::{self, Impossible, Serialize, Serializer};
use std::fmt;

/// The serde name of `value`'s variant (after `rename_all`): "cubic" for
/// `KernelType::Cubic`, "lobpcg" for `SolverConfig::Lobpcg(..)`. `value` must be an enum
/// with a derived (externally tagged) `Serialize`; anything else has no variant and gives "".
pub fn variant_name<T: Serialize + ?Sized>(value: &T) -> &'static str {
    value.serialize(VariantName).unwrap_or("")
}

/// The value of an enum of unit variants named `name` (its serde spelling), None if no
/// variant has that name.
pub fn from_name<T: DeserializeOwned>(name: &str) -> Option<T> {
    T::deserialize(StrDeserializer::<ValueError>::new(name)).ok()
}

/// A serializer that only records which variant it was handed.
struct VariantName;

/// Not an enum variant.
#[derive(Debug)]
struct NotAVariant;

impl fmt::Display for NotAVariant {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("not an enum variant")
    }
}

impl std::error::Error for NotAVariant {}

impl ser::Error for NotAVariant {
    fn custom<M: fmt::Display>(_: M) -> Self {
        NotAVariant
    }
}

/// A tuple or struct variant: its name, whatever its fields.
struct Named(&'static str);

impl ser::SerializeTupleVariant for Named {
    type Ok = &'static str;
    type Error = NotAVariant;
    fn serialize_field<F: Serialize + ?Sized>(&mut self, _: &F) -> Result<(), NotAVariant> {
        Ok(())
    }
    fn end(self) -> Result<&'static str, NotAVariant> {
        Ok(self.0)
    }
}

impl ser::SerializeStructVariant for Named {
    type Ok = &'static str;
    type Error = NotAVariant;
    fn serialize_field<F: Serialize + ?Sized>(
        &mut self,
        _: &'static str,
        _: &F,
    ) -> Result<(), NotAVariant> {
        Ok(())
    }
    fn end(self) -> Result<&'static str, NotAVariant> {
        Ok(self.0)
    }
}

/// The methods of a value that is not an enum variant: all refuse.
macro_rules! refuse {
    ($($name:ident($($arg:ty),*)),* $(,)?) => {
        $(fn $name(self, $(_: $arg),*) -> Result<&'static str, NotAVariant> {
            Err(NotAVariant)
        })*
    };
}

impl Serializer for VariantName {
    type Ok = &'static str;
    type Error = NotAVariant;
    type SerializeSeq = Impossible<&'static str, NotAVariant>;
    type SerializeTuple = Impossible<&'static str, NotAVariant>;
    type SerializeTupleStruct = Impossible<&'static str, NotAVariant>;
    type SerializeTupleVariant = Named;
    type SerializeMap = Impossible<&'static str, NotAVariant>;
    type SerializeStruct = Impossible<&'static str, NotAVariant>;
    type SerializeStructVariant = Named;

    fn serialize_unit_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
    ) -> Result<&'static str, NotAVariant> {
        Ok(variant)
    }

    fn serialize_newtype_variant<V: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: &V,
    ) -> Result<&'static str, NotAVariant> {
        Ok(variant)
    }

    fn serialize_tuple_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Named, NotAVariant> {
        Ok(Named(variant))
    }

    fn serialize_struct_variant(
        self,
        _: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Named, NotAVariant> {
        Ok(Named(variant))
    }

    refuse!(
        serialize_bool(bool),
        serialize_i8(i8),
        serialize_i16(i16),
        serialize_i32(i32),
        serialize_i64(i64),
        serialize_u8(u8),
        serialize_u16(u16),
        serialize_u32(u32),
        serialize_u64(u64),
        serialize_f32(f32),
        serialize_f64(f64),
        serialize_char(char),
        serialize_str(&str),
        serialize_bytes(&[u8]),
        serialize_none(),
        serialize_unit(),
        serialize_unit_struct(&'static str),
    );

    fn serialize_some<V: Serialize + ?Sized>(self, _: &V) -> Result<&'static str, NotAVariant> {
        Err(NotAVariant)
    }

    fn serialize_newtype_struct<V: Serialize + ?Sized>(
        self,
        _: &'static str,
        _: &V,
    ) -> Result<&'static str, NotAVariant> {
        Err(NotAVariant)
    }

    fn serialize_seq(self, _: Option<usize>) -> Result<Self::SerializeSeq, NotAVariant> {
        Err(NotAVariant)
    }

    fn serialize_tuple(self, _: usize) -> Result<Self::SerializeTuple, NotAVariant> {
        Err(NotAVariant)
    }

    fn serialize_tuple_struct(
        self,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleStruct, NotAVariant> {
        Err(NotAVariant)
    }

    fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, NotAVariant> {
        Err(NotAVariant)
    }

    fn serialize_struct(
        self,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStruct, NotAVariant> {
        Err(NotAVariant)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::{Deserialize, Serialize};

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    #[serde(rename_all = "snake_case")]
    enum Kind {
        FixSide,
        Lobpcg(f64),
        Pair(u8, u8),
        Named { a: f64 },
    }

    #[test]
    fn names_are_the_serde_spellings_and_parse_back() {
        assert_eq!(variant_name(&Kind::FixSide), "fix_side");
        assert_eq!(variant_name(&Kind::Lobpcg(1.0)), "lobpcg");
        assert_eq!(variant_name(&Kind::Pair(1, 2)), "pair");
        assert_eq!(variant_name(&Kind::Named { a: 1.0 }), "named");
        assert_eq!(variant_name(&3.0), "");
        assert_eq!(from_name::<Kind>("fix_side"), Some(Kind::FixSide));
        assert_eq!(from_name::<Kind>("FixSide"), None);
    }
}
