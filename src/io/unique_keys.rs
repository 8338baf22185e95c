//! Maps read from YAML or JSON with every key given once: serde keeps the last
//! of two equal keys without a word, so a file could say two things and be
//! read as one of them. Use with `#[serde(deserialize_with = "...")]`, or read
//! whole JSON files with [`json`] and [`json_value`].

use std::collections::BTreeMap;
use std::fmt;
use std::marker::PhantomData;

use serde::de::{Deserialize, Deserializer, Error, MapAccess, Visitor};

struct UniqueMap<K, V>(PhantomData<(K, V)>);

impl<'de, K, V> Visitor<'de> for UniqueMap<K, V>
where
    K: Deserialize<'de> + Ord + fmt::Display,
    V: Deserialize<'de>,
{
    type Value = BTreeMap<K, V>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a map whose keys are all different")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut access: A) -> Result<Self::Value, A::Error> {
        let mut out = BTreeMap::new();
        while let Some(key) = access.next_key::<K>()? {
            if out.contains_key(&key) {
                return Err(A::Error::custom(format!(
                    "`{key}` is given twice; a key may be given once"
                )));
            }
            let value = access.next_value()?;
            out.insert(key, value);
        }
        Ok(out)
    }
}

/// A map that refuses a key given twice.
pub fn map<'de, D, K, V>(d: D) -> Result<BTreeMap<K, V>, D::Error>
where
    D: Deserializer<'de>,
    K: Deserialize<'de> + Ord + fmt::Display,
    V: Deserialize<'de>,
{
    d.deserialize_map(UniqueMap(PhantomData))
}

/// A map of maps, neither of which may give a key twice.
pub fn map_of_maps<'de, D, V>(d: D) -> Result<BTreeMap<String, BTreeMap<String, V>>, D::Error>
where
    D: Deserializer<'de>,
    V: Deserialize<'de>,
{
    struct Inner<V>(BTreeMap<String, V>);
    impl<'de, V: Deserialize<'de>> Deserialize<'de> for Inner<V> {
        fn deserialize<D2: Deserializer<'de>>(d: D2) -> Result<Self, D2::Error> {
            map(d).map(Inner)
        }
    }
    let outer: BTreeMap<String, Inner<V>> = map(d)?;
    Ok(outer.into_iter().map(|(k, v)| (k, v.0)).collect())
}

/// A JSON value of any shape in which no object gives a key twice.
struct UniqueJson(serde_json::Value);

impl<'de> Deserialize<'de> for UniqueJson {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_any(UniqueJsonVisitor).map(UniqueJson)
    }
}

struct UniqueJsonVisitor;

impl<'de> Visitor<'de> for UniqueJsonVisitor {
    type Value = serde_json::Value;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("JSON whose objects give every key once")
    }
    fn visit_bool<E: Error>(self, v: bool) -> Result<Self::Value, E> {
        Ok(v.into())
    }
    fn visit_i64<E: Error>(self, v: i64) -> Result<Self::Value, E> {
        Ok(v.into())
    }
    fn visit_u64<E: Error>(self, v: u64) -> Result<Self::Value, E> {
        Ok(v.into())
    }
    fn visit_f64<E: Error>(self, v: f64) -> Result<Self::Value, E> {
        Ok(v.into())
    }
    fn visit_str<E: Error>(self, v: &str) -> Result<Self::Value, E> {
        Ok(v.into())
    }
    fn visit_string<E: Error>(self, v: String) -> Result<Self::Value, E> {
        Ok(v.into())
    }
    fn visit_unit<E: Error>(self) -> Result<Self::Value, E> {
        Ok(serde_json::Value::Null)
    }
    fn visit_none<E: Error>(self) -> Result<Self::Value, E> {
        Ok(serde_json::Value::Null)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut access: A) -> Result<Self::Value, A::Error> {
        let mut items = Vec::new();
        while let Some(UniqueJson(v)) = access.next_element()? {
            items.push(v);
        }
        Ok(serde_json::Value::Array(items))
    }
    fn visit_map<A: MapAccess<'de>>(self, mut access: A) -> Result<Self::Value, A::Error> {
        let mut out = serde_json::Map::new();
        while let Some(key) = access.next_key::<String>()? {
            if out.contains_key(&key) {
                return Err(A::Error::custom(format!(
                    "`{key}` is given twice; a key may be given once"
                )));
            }
            let UniqueJson(value) = access.next_value()?;
            out.insert(key, value);
        }
        Ok(serde_json::Value::Object(out))
    }
}

/// `text` read as JSON, refused (at the line of the second) when any object
/// in it gives a key twice.
pub fn json_value(text: &str) -> Result<serde_json::Value, serde_json::Error> {
    serde_json::from_str::<UniqueJson>(text).map(|u| u.0)
}

/// `text` read as JSON into `T`, refused when any object gives a key twice
/// (which `T`'s own maps would keep the last of).
pub fn json<T: serde::de::DeserializeOwned>(text: &str) -> Result<T, serde_json::Error> {
    json_value(text)?;
    serde_json::from_str(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    struct Doc {
        #[serde(deserialize_with = "map_of_maps")]
        datasets: BTreeMap<String, BTreeMap<String, f64>>,
    }

    #[test]
    fn a_key_given_twice_is_refused_at_its_line() {
        let ok: Doc = serde_yaml::from_str("datasets:\n  a:\n    x: 1\n  b:\n    x: 2\n").unwrap();
        assert_eq!(ok.datasets["b"]["x"], 2.0);
        let outer = serde_yaml::from_str::<Doc>("datasets:\n  a:\n    x: 1\n  a:\n    x: 9\n").unwrap_err();
        assert!(outer.to_string().contains("`a` is given twice"), "{outer}");
        assert!(outer.to_string().contains("line"), "{outer}");
        let inner = serde_yaml::from_str::<Doc>("datasets:\n  a:\n    x: 1\n    x: 9\n").unwrap_err();
        assert!(inner.to_string().contains("`x` is given twice"), "{inner}");
        let json = serde_json::from_str::<Doc>(r#"{"datasets": {"a": {"x": 1, "x": 9}}}"#).unwrap_err();
        assert!(json.to_string().contains("`x` is given twice"), "{json}");
    }

    #[test]
    fn json_of_any_shape_gives_every_key_once() {
        let text = "{\"a\": [1, {\"b\": null}], \"c\": {\"d\": 2.5, \"e\": \"x\"}, \"f\": true}";
        assert_eq!(
            json_value(text).unwrap(),
            serde_json::from_str::<serde_json::Value>(text).unwrap()
        );
        let deep = json_value("{\"a\": [1, {\"b\": 1,\n \"b\": 2}]}").unwrap_err();
        assert!(deep.to_string().contains("`b` is given twice"), "{deep}");
        assert_eq!(deep.line(), 2, "{deep}");
        let top = json::<serde_json::Value>("{\"kind\": 1, \"kind\": 2}").unwrap_err();
        assert!(top.to_string().contains("`kind` is given twice"), "{top}");
    }
}
