// Draws a mesh with one colour per vertex (Gouraud shading), the GPU twin of the CPU rasteriser
// in src/relight/raster.rs. The colours are read from a storage buffer of vec4<f32> per vertex,
// indexed by the vertex's index (an indexed draw's vertex_index is the index value), so a relit
// buffer can be drawn without leaving the GPU. Clip space (`clip_from_world`) puts x right and y
// up over the film, w the forward distance from the eye and z the near distance, so the depth is
// near / w: reversed depth, cleared to 0 and tested with `greater`. Coverage is the alpha.

struct View {
    clip_from_world: mat4x4<f32>,
};

@group(0) @binding(0) var<uniform> view: View;
@group(0) @binding(1) var<storage, read> colours: array<vec4<f32>>;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    // Perspective-correct, like the CPU twin's barycentrics of the hit point.
    @location(0) colour: vec3<f32>,
};

@vertex
fn vertex(@location(0) position: vec3<f32>, @builtin(vertex_index) index: u32) -> Varyings {
    var out: Varyings;
    out.position = view.clip_from_world * vec4<f32>(position, 1.0);
    out.colour = colours[index].rgb;
    return out;
}

@fragment
fn fragment(in: Varyings) -> @location(0) vec4<f32> {
    return vec4<f32>(in.colour, 1.0);
}
