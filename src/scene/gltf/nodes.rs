//! The node walk: each node's transform down the hierarchy, and the meshes, cameras and
//! `KHR_lights_punctual` lights it places in the world.

use glam::{Mat3, Mat4, Quat, Vec3};
use gltf::json::extensions::scene::khr_lights_punctual::Type as LightType;

use super::{GltfCamera, LUMENS_PER_WATT, Reader, printable};
use crate::error::Result;
use crate::scene::MAX_COORDINATE;
use crate::scene::light::{Light, LightShape, MAX_LIGHT_COLUMNS, valid_name};

impl Reader<'_> {
    /// Walks the scene's nodes, placing meshes, cameras and lights.
    pub(super) fn walk(&mut self, placement: Mat4) -> Result<()> {
        let nodes = self.doc.as_json().nodes.len();
        let roots: Vec<usize> = match self
            .doc
            .default_scene()
            .or_else(|| self.doc.scenes().next())
        {
            Some(scene) => scene.nodes().map(|n| n.index()).collect(),
            None => {
                let mut child = vec![false; nodes];
                for n in self.doc.nodes() {
                    for c in n.children() {
                        child[c.index()] = true;
                    }
                }
                (0..nodes).filter(|&i| !child[i]).collect()
            }
        };
        let mut seen = vec![false; nodes];
        let mut stack: Vec<(usize, Mat4)> =
            roots.into_iter().rev().map(|i| (i, placement)).collect();
        while let Some((i, parent)) = stack.pop() {
            if std::mem::replace(&mut seen[i], true) {
                return Err(self.error(
                    format!("nodes[{i}]"),
                    "the node appears twice in the hierarchy (a cycle, or a child of two parents)",
                ));
            }
            let world = parent * self.local_transform(i)?;
            let node = self.doc.nodes().nth(i).expect("validated node index");
            if let Some(mesh) = node.mesh() {
                self.place_mesh(&mesh, i, world)?;
            }
            if let Some(c) = node.camera() {
                self.place_camera(c.index(), i, world);
            }
            self.place_light(i, world)?;
            for c in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push((c.index(), world));
            }
        }
        Ok(())
    }

    /// Node `i`'s transform: its `matrix`, or translation · rotation · scale.
    fn local_transform(&self, i: usize) -> Result<Mat4> {
        let n = &self.doc.as_json().nodes[i];
        let m = match n.matrix {
            Some(m) => Mat4::from_cols_array(&m),
            None => {
                let t = Vec3::from(n.translation.unwrap_or([0.0; 3]));
                let r = n.rotation.map_or(Quat::IDENTITY, |q| Quat::from_array(q.0));
                let s = Vec3::from(n.scale.unwrap_or([1.0; 3]));
                if !(r.is_finite() && r.length() > 0.5) {
                    return Err(self.error(
                        format!("nodes[{i}].rotation"),
                        format!("{r} is not a unit quaternion"),
                    ));
                }
                Mat4::from_scale_rotation_translation(s, r.normalize(), t)
            }
        };
        if !m.is_finite() || m.abs().to_cols_array().iter().any(|&v| v > MAX_COORDINATE) {
            return Err(self.error(format!("nodes[{i}]"), "the transform is not finite"));
        }
        Ok(m)
    }

    fn place_camera(&mut self, index: usize, node: usize, world: Mat4) {
        let json = &self.doc.as_json().cameras[index];
        let name = json
            .name
            .as_deref()
            .map(printable)
            .unwrap_or_else(|| format!("camera {index}"));
        let perspective = json.type_
            == gltf::json::validation::Checked::Valid(gltf::json::camera::Type::Perspective);
        let Some(p) = json.perspective.as_ref().filter(|_| perspective) else {
            self.out.ignored.insert(format!(
                "orthographic camera {name} (cameras are perspective)"
            ));
            return;
        };
        let frame = Mat3::from_mat4(world);
        let (forward, up) = (
            (frame * Vec3::NEG_Z).normalize_or_zero(),
            (frame * Vec3::Y).normalize_or_zero(),
        );
        let fov_y_deg = p.yfov.to_degrees();
        if forward == Vec3::ZERO || up == Vec3::ZERO || !(fov_y_deg > 0.0 && fov_y_deg < 180.0) {
            self.out.ignored.insert(format!(
                "camera {name} at node {node} (a degenerate transform or field of view)"
            ));
            return;
        }
        self.out.cameras.push(GltfCamera {
            name,
            eye: world.transform_point3(Vec3::ZERO),
            forward,
            up,
            fov_y_deg,
            aspect: p.aspect_ratio.filter(|a| a.is_finite() && *a > 0.0),
        });
    }

    fn place_light(&mut self, node: usize, world: Mat4) -> Result<()> {
        let json = self.doc.as_json();
        let Some(ext) = json.nodes[node]
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
        else {
            return Ok(());
        };
        let index = ext.light.value();
        let field = format!("nodes[{node}].extensions.KHR_lights_punctual.light");
        let Some(l) = json
            .extensions
            .as_ref()
            .and_then(|e| e.khr_lights_punctual.as_ref())
            .and_then(|k| k.lights.get(index))
        else {
            return Err(self.error(field, format!("light {index} is not defined")));
        };
        let direction = (Mat3::from_mat4(world) * Vec3::NEG_Z).normalize_or_zero();
        let position = world.transform_point3(Vec3::ZERO);
        let shape = match l.type_ {
            gltf::json::validation::Checked::Valid(LightType::Point) => LightShape::Point,
            gltf::json::validation::Checked::Valid(LightType::Directional) => {
                LightShape::Directional {
                    direction,
                    angle: 0.0,
                }
            }
            gltf::json::validation::Checked::Valid(LightType::Spot) => {
                let Some(spot) = l.spot.as_ref() else {
                    return Err(
                        self.error(format!("lights[{index}].spot"), "a spot light needs `spot`")
                    );
                };
                let (inner, outer) = (spot.inner_cone_angle, spot.outer_cone_angle);
                if !(0.0 <= inner
                    && inner <= outer
                    && outer > 0.0
                    && outer <= std::f32::consts::FRAC_PI_2)
                {
                    return Err(self.error(
                        format!("lights[{index}].spot"),
                        format!("needs 0 <= innerConeAngle <= outerConeAngle <= π/2, outerConeAngle > 0, got {inner} and {outer}"),
                    ));
                }
                LightShape::Spot {
                    direction,
                    cone: outer,
                    falloff: outer - inner,
                }
            }
            _ => return Err(self.error(format!("lights[{index}].type"), "unknown light type")),
        };
        let base = l
            .name
            .as_deref()
            .map(|n| {
                n.chars()
                    .filter(|c| c.is_ascii())
                    .map(|c| {
                        if c.is_ascii_alphanumeric() || "_-.".contains(c) {
                            c
                        } else {
                            '_'
                        }
                    })
                    .take(56)
                    .collect::<String>()
            })
            .filter(|n| !n.is_empty())
            .unwrap_or_else(|| format!("light{index}"));
        if self.out.lights.len() >= MAX_LIGHT_COLUMNS {
            return Err(self.error(
                format!("{field} (light {index})"),
                format!("the file places more than {MAX_LIGHT_COLUMNS} lights"),
            ));
        }
        // A name used already takes the first free suffix (its base is at most 56 bytes, so the
        // name stays within 64).
        let mut name = base.clone();
        let mut k = 2;
        while !self.light_names.insert(name.clone()) {
            name = format!("{base}.{k}");
            k += 1;
        }
        debug_assert!(valid_name(&name));
        let intensity = l.intensity / LUMENS_PER_WATT;
        if l.range.is_some() {
            self.out
                .ignored
                .insert("light range (lights fall off with the inverse square of distance)".into());
        }
        let light = Light {
            name,
            color: Vec3::from(l.color),
            intensity,
            shape,
            positions: vec![position],
            grid: [1, 1, 1],
        };
        // The intensity's range is the rule every light is held to (`Light::problem`).
        if let Some(problem) = light.problem() {
            return Err(self.error(format!("lights[{index}]"), problem));
        }
        self.out.lights.push(light);
        Ok(())
    }
}
