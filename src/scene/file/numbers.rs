//! The scene file's numbers: fixed-length arrays read at exactly their length, and the checks of
//! its vectors and positions. serde reads an array `[T; N]` by taking N elements and stops there,
//! so a longer array would lose its extra elements silently; these readers refuse any length but
//! N, naming the length expected and the one given.

use std::fmt;
use std::marker::PhantomData;

use glam::Vec3;
use serde::Deserialize;
use serde::de::{Deserializer, Error as _, IgnoredAny, SeqAccess, Visitor};

use crate::error::Result;
use crate::scene::diagnostics::SourceMap;

/// Largest coordinate of a point in a scene (camera, shapes, medium), in scene units. The BVH
/// builder and the ray tests multiply and sum extents, which overflow f32 near 1e19; at 1e9 an
/// f32 still resolves 64 units, far beyond any scene that makes sense.
pub const MAX_COORDINATE: f32 = 1e9;

pub(super) fn finite3(map: &SourceMap, field: &str, v: [f32; 3]) -> Result<Vec3> {
    let v = Vec3::from_array(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(map.error(field, format!("must be finite, got {v}")))
    }
}

/// [`finite3`] for a position or size: finite and within ±[`MAX_COORDINATE`].
pub(super) fn position3(map: &SourceMap, field: &str, v: [f32; 3]) -> Result<Vec3> {
    let v = finite3(map, field, v)?;
    if v.abs().max_element() > MAX_COORDINATE {
        return Err(map.error(
            field,
            format!("{v} lies beyond ±{MAX_COORDINATE:e} scene units"),
        ));
    }
    Ok(v)
}

/// What the elements of a fixed-length array are called in its length error.
pub(super) trait Element {
    /// The elements, plural: "numbers", "points".
    const PLURAL: &'static str;
}

impl Element for f32 {
    const PLURAL: &'static str = "numbers";
}

impl Element for u32 {
    const PLURAL: &'static str = "numbers";
}

impl Element for Exact<f32, 3> {
    const PLURAL: &'static str = "points";
}

/// An array of exactly `N` elements.
struct Exact<T, const N: usize>([T; N]);

impl<'de, T: Deserialize<'de> + Element, const N: usize> Deserialize<'de> for Exact<T, N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        d.deserialize_seq(ExactVisitor::<T, N>(PhantomData))
    }
}

struct ExactVisitor<T, const N: usize>(PhantomData<T>);

impl<'de, T: Deserialize<'de> + Element, const N: usize> Visitor<'de> for ExactVisitor<T, N> {
    type Value = Exact<T, N>;

    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        write!(f, "an array of {N} {}", T::PLURAL)
    }

    fn visit_seq<A: SeqAccess<'de>>(
        self,
        mut seq: A,
    ) -> std::result::Result<Self::Value, A::Error> {
        let mut items = Vec::with_capacity(N);
        while items.len() < N {
            match seq.next_element::<T>()? {
                Some(x) => items.push(x),
                None => break,
            }
        }
        // Past N the elements are only counted, for the message.
        let mut got = items.len();
        while seq.next_element::<IgnoredAny>()?.is_some() {
            got += 1;
        }
        match <[T; N]>::try_from(items) {
            Ok(array) if got == N => Ok(Exact(array)),
            _ => Err(A::Error::custom(format!(
                "expected {N} {}, got {got}",
                T::PLURAL
            ))),
        }
    }
}

/// `N` numbers, exactly.
pub(super) fn numbers<'de, D, T, const N: usize>(d: D) -> std::result::Result<[T; N], D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Element,
{
    Exact::<T, N>::deserialize(d).map(|a| a.0)
}

/// [`numbers`] of an optional key (which needs `#[serde(default)]` beside it).
pub(super) fn some_numbers<'de, D, T, const N: usize>(
    d: D,
) -> std::result::Result<Option<[T; N]>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Element,
{
    Option::<Exact<T, N>>::deserialize(d).map(|o| o.map(|a| a.0))
}

/// `N` points of 3 numbers each, exactly.
pub(super) fn points<'de, D, const N: usize>(d: D) -> std::result::Result<[[f32; 3]; N], D::Error>
where
    D: Deserializer<'de>,
{
    Exact::<Exact<f32, 3>, N>::deserialize(d).map(|a| a.0.map(|p| p.0))
}

/// [`points`] of an optional key (which needs `#[serde(default)]` beside it).
pub(super) fn some_points<'de, D, const N: usize>(
    d: D,
) -> std::result::Result<Option<[[f32; 3]; N]>, D::Error>
where
    D: Deserializer<'de>,
{
    Option::<Exact<Exact<f32, 3>, N>>::deserialize(d).map(|o| o.map(|a| a.0.map(|p| p.0)))
}

/// A list of any length of points of 3 numbers each, of an optional key (which needs
/// `#[serde(default)]` beside it).
pub(super) fn some_point_list<'de, D>(d: D) -> std::result::Result<Option<Vec<[f32; 3]>>, D::Error>
where
    D: Deserializer<'de>,
{
    Option::<Vec<Exact<f32, 3>>>::deserialize(d)
        .map(|o| o.map(|list| list.into_iter().map(|p| p.0).collect()))
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use crate::scene::Scene;
    use crate::test_support::CANONICAL;

    /// The canonical scene with a point light.
    fn lit() -> String {
        format!(
            "{CANONICAL}\n[[light]]\nname = \"lamp\"\ntype = \"point\"\n\
             position = [0.0, 2.0, 0.0]\nintensity = 1.0\ncolor = [1.0, 0.9, 0.8]\n"
        )
    }

    /// The error of loading `text`, which must be refused.
    fn refused(text: &str) -> String {
        Scene::from_toml_str(text, Path::new("/scenes/test.toml"))
            .expect_err("the scene should be refused")
            .to_string()
    }

    /// `text` with `from` (which it must hold) replaced by `to`.
    fn edited(text: &str, from: &str, to: &str) -> String {
        assert!(text.contains(from), "`{from}` not in the scene");
        text.replacen(from, to, 1)
    }

    #[test]
    fn arrays_of_the_wrong_length_are_refused_with_the_length_expected() {
        Scene::from_toml_str(&lit(), Path::new("/scenes/test.toml")).expect("the scene loads");
        let quad = "[2.0, 0.0, 2.0], [2.0, 0.0, -2.0]]";
        for (from, to, field, want) in [
            // A fifth quad corner.
            (
                quad,
                "[2.0, 0.0, 2.0], [2.0, 0.0, -2.0], [0.0, 0.0, 0.0]]",
                "shape[0].corners",
                "expected 4 points, got 5",
            ),
            // A corner of 4 numbers.
            (
                quad,
                "[2.0, 0.0, 2.0, 1.0], [2.0, 0.0, -2.0]]",
                "shape[0].corners[2]",
                "expected 3 numbers, got 4",
            ),
            (
                "eye = [0.0, 1.5, 4.0]",
                "eye = [0.0, 1.5, 4.0, 1.0]",
                "camera.eye",
                "expected 3 numbers, got 4",
            ),
            (
                "eye = [0.0, 1.5, 4.0]",
                "eye = [0.0, 1.5]",
                "camera.eye",
                "expected 3 numbers, got 2",
            ),
            (
                "color = [1.0, 0.9, 0.8]",
                "color = [1.0, 0.9, 0.8, 0.7]",
                "light[0].color",
                "expected 3 numbers, got 4",
            ),
            (
                "albedo = [0.8, 0.3, 0.2]",
                "albedo = [0.8, 0.3, 0.2, 0.1]",
                "material.clay.albedo",
                "expected 3 numbers, got 4",
            ),
            (
                "center = [0.0, 0.6, 0.0]",
                "center = [0.0, 0.6, 0.0, 0.0]",
                "shape[1].center",
                "expected 3 numbers, got 4",
            ),
            (
                "position = [0.0, 2.0, 0.0]",
                "positions = [[0.0, 2.0, 0.0], [1.0, 2.0, 0.0, 5.0]]",
                "light[0].positions[1]",
                "expected 3 numbers, got 4",
            ),
            (
                "position = [0.0, 2.0, 0.0]",
                "grid = { from = [0.0, 2.0, 0.0], to = [1.0, 2.0, 0.0], counts = [2, 1, 1, 1] }",
                "light[0].grid.counts",
                "expected 3 numbers, got 4",
            ),
        ] {
            let e = refused(&edited(&lit(), from, to));
            assert!(
                e.contains(&format!("field `{field}`")) && e.contains(want),
                "{to}: {e}"
            );
        }
    }

    #[test]
    fn a_medium_takes_exactly_two_bounds() {
        let fog = "\n[medium]\ntype = \"ellipsoid\"\nextinction = 1.0\n";
        let ok = format!("{CANONICAL}{fog}bounds = [[-1.0, 0.0, -1.0], [1.0, 1.0, 1.0]]\n");
        Scene::from_toml_str(&ok, Path::new("/scenes/test.toml")).expect("the scene loads");
        let e = refused(&edited(
            &ok,
            "[1.0, 1.0, 1.0]]",
            "[1.0, 1.0, 1.0], [2.0, 2.0, 2.0]]",
        ));
        assert!(
            e.contains("field `medium.bounds`") && e.contains("expected 2 points, got 3"),
            "{e}"
        );
    }
}
