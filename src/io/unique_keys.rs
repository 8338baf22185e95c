//! Maps read from YAML or JSON with every key given once: serde keeps the last
//! of two equal keys without a word, so a file could say two things and be
//! read as one of them. Use with `#[serde(deserialize_with = "...")]`.

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
}
