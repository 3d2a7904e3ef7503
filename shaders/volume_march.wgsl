// Ray-marched relighting of a medium from its SH self-transfer (src/volume/render.rs is the CPU
// twin, step for step): one thread per pixel marches its camera ray in half-voxel steps through
// the density's support, and at each sample adds T_cam · sigma_t · dt · albedo · Σ_i P_i(d) T_i(x),
// with T_i trilinear (clamped) from the transfer grid and P(d) bilinear from the phase-light table.
// Scattering of orders 2 and above adds T_cam · sigma_t · dt · Σ_a g^l Y_a(d) F_a(x), with the
// light's scattered field F (albedo powers included) trilinear like the transfer.

struct Params {
    eye: vec3<f32>,
    width: u32,
    forward: vec3<f32>,
    height: u32,
    right: vec3<f32>,       // camera right · tan(fov/2) · aspect
    n2: u32,
    up: vec3<f32>,          // film up · tan(fov/2)
    view: u32,              // 0 full, 1 in-scatter, 2 transmittance, 3 transfer DC
    grid_min: vec3<f32>,
    table_w: u32,
    cell: vec3<f32>,
    table_h: u32,
    dims: vec3<u32>,
    extinction: f32,
    albedo: vec3<f32>,
    step: f32,
    g: f32,
    ms_n2: u32,             // coefficients of the scattered field per voxel (0: single scattering)
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> density: array<f32>;
@group(0) @binding(2) var<storage, read> transfer: array<f32>;
@group(0) @binding(3) var<storage, read> table: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> image: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> scatter: array<vec4<f32>>;

const PI: f32 = 3.14159265358979;
const MAX_N2: u32 = 64u;

// Real SH to band 2 in the project's convention (CONVENTIONS.md: Condon–Shortley phase, +z
// polar), times g^l: the weights of the scattered field's coefficients along d, in registers
// (bands 0-1 in `low`, band 2 in `high` and `last`) so that no per-sample loop indexes an array.
struct FieldWeights {
    low: vec4<f32>,
    high: vec4<f32>,
    last: f32,
}

fn field_weights(d: vec3<f32>, g: f32) -> FieldWeights {
    let g2 = g * g;
    return FieldWeights(
        vec4<f32>(0.2820948, -0.4886025 * d.y * g, 0.4886025 * d.z * g, -0.4886025 * d.x * g),
        vec4<f32>(
            1.0925484 * d.x * d.y * g2,
            -1.0925484 * d.y * d.z * g2,
            0.3153916 * (3.0 * d.z * d.z - 1.0) * g2,
            -1.0925484 * d.x * d.z * g2,
        ),
        0.5462742 * (d.x * d.x - d.y * d.y) * g2,
    );
}

// The scattered field of one voxel along the march's direction: Σ_a w_a F_a (1, 4 or 9
// coefficients a voxel).
fn field_at(voxel: u32, cw: FieldWeights) -> vec3<f32> {
    let n = params.ms_n2;
    let b = voxel * n;
    var s = cw.low.x * scatter[b].xyz;
    if n >= 4u {
        s += cw.low.y * scatter[b + 1u].xyz + cw.low.z * scatter[b + 2u].xyz
            + cw.low.w * scatter[b + 3u].xyz;
    }
    if n >= 9u {
        s += cw.high.x * scatter[b + 4u].xyz + cw.high.y * scatter[b + 5u].xyz
            + cw.high.z * scatter[b + 6u].xyz + cw.high.w * scatter[b + 7u].xyz
            + cw.last * scatter[b + 8u].xyz;
    }
    return s;
}

fn voxel(x: i32, y: i32, z: i32) -> f32 {
    let d = vec3<i32>(params.dims);
    if x < 0 || y < 0 || z < 0 || x >= d.x || y >= d.y || z >= d.z {
        return 0.0;
    }
    return density[u32((z * d.y + y) * d.x + x)];
}

// Trilinear density between voxel centres, zero outside (as DensityGrid::density).
fn sigma_t(p: vec3<f32>) -> f32 {
    let u = (p - params.grid_min) / params.cell - 0.5;
    let i = floor(u);
    let f = u - i;
    let x = i32(i.x);
    let y = i32(i.y);
    let z = i32(i.z);
    let c00 = mix(voxel(x, y, z), voxel(x + 1, y, z), f.x);
    let c10 = mix(voxel(x, y + 1, z), voxel(x + 1, y + 1, z), f.x);
    let c01 = mix(voxel(x, y, z + 1), voxel(x + 1, y, z + 1), f.x);
    let c11 = mix(voxel(x, y + 1, z + 1), voxel(x + 1, y + 1, z + 1), f.x);
    return params.extinction * mix(mix(c00, c10, f.y), mix(c01, c11, f.y), f.z);
}

fn safe_inv(c: f32) -> f32 {
    if abs(c) < 1e-30 {
        return select(-1e30, 1e30, c >= 0.0);
    }
    return 1.0 / c;
}

// Clamped trilinear coordinates along one axis: (i0, i1, fraction).
fn axis_coord(v: f32, n: u32) -> vec3<f32> {
    let c = clamp(v, 0.0, f32(n - 1u));
    let i = min(u32(floor(c)), max(n, 2u) - 2u);
    let i1 = min(i + 1u, n - 1u);
    return vec3<f32>(f32(i), f32(i1), c - f32(i));
}

@compute @workgroup_size(WG_X, WG_Y)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if id.x >= params.width || id.y >= params.height {
        return;
    }
    let sx = 2.0 * (f32(id.x) + 0.5) / f32(params.width) - 1.0;
    let sy = 1.0 - 2.0 * (f32(id.y) + 0.5) / f32(params.height);
    let dir = normalize(params.forward + sx * params.right + sy * params.up);
    let o = params.eye;
    let out_index = id.y * params.width + id.x;

    // P(d), bilinear in the lat-long table (u wraps).
    var p: array<vec3<f32>, MAX_N2>;
    let n2 = params.n2;
    if params.table_w * params.table_h == 1u {
        for (var i = 0u; i < n2; i++) {
            p[i] = table[i].xyz;
        }
    } else {
        let v = acos(clamp(dir.y, -1.0, 1.0)) / PI;
        var u = atan2(dir.x, -dir.z) / (2.0 * PI);
        if u < 0.0 {
            u += 1.0;
        }
        let tw = params.table_w;
        let th = params.table_h;
        let x = u * f32(tw) - 0.5;
        let y = clamp(v * f32(th) - 0.5, 0.0, f32(th - 1u));
        let x0 = floor(x);
        let y0 = floor(y);
        let fx = x - x0;
        let fy = y - y0;
        let xa = u32((i32(x0) % i32(tw) + i32(tw)) % i32(tw));
        let xb = u32((i32(x0 + 1.0) % i32(tw) + i32(tw)) % i32(tw));
        let ya = u32(y0);
        let yb = min(ya + 1u, th - 1u);
        for (var i = 0u; i < n2; i++) {
            p[i] = (1.0 - fx) * (1.0 - fy) * table[(ya * tw + xa) * n2 + i].xyz
                + fx * (1.0 - fy) * table[(ya * tw + xb) * n2 + i].xyz
                + (1.0 - fx) * fy * table[(yb * tw + xa) * n2 + i].xyz
                + fx * fy * table[(yb * tw + xb) * n2 + i].xyz;
        }
    }

    // The density's support: the grid box grown by half a voxel.
    let lo = params.grid_min - 0.5 * params.cell;
    let hi = params.grid_min + (vec3<f32>(params.dims) + 0.5) * params.cell;
    let inv = vec3<f32>(safe_inv(dir.x), safe_inv(dir.y), safe_inv(dir.z));
    let a = (lo - o) * inv;
    let b = (hi - o) * inv;
    let tmin = min(a, b);
    let tmax = max(a, b);
    let t0 = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    let t1 = min(min(tmax.x, tmax.y), tmax.z);
    var sum = vec3<f32>(0.0);
    var more = vec3<f32>(0.0);
    let ms_n2 = params.ms_n2;
    let cw = field_weights(dir, params.g);
    var transmittance = 1.0;
    if t1 > t0 {
        let steps = max(ceil((t1 - t0) / params.step), 1.0);
        let dt = (t1 - t0) / steps;
        let n = u32(steps);
        let dims = params.dims;
        for (var k = 0u; k < n; k++) {
            let pos = o + dir * (t0 + (f32(k) + 0.5) * dt);
            let sigma = sigma_t(pos);
            if sigma <= 0.0 {
                continue;
            }
            let half_t = exp(-0.5 * sigma * dt);
            var weight = transmittance * half_t * sigma * dt;
            if params.view == 1u {
                weight = sigma * dt;
            }
            transmittance *= half_t * half_t;
            if params.view != 2u {
                // Clamped trilinear transfer.
                let u = (pos - params.grid_min) / params.cell - 0.5;
                let cx = axis_coord(u.x, dims.x);
                let cy = axis_coord(u.y, dims.y);
                let cz = axis_coord(u.z, dims.z);
                var acc = vec3<f32>(0.0);
                var acc_ms = vec3<f32>(0.0);
                for (var corner = 0u; corner < 8u; corner++) {
                    let bx = corner & 1u;
                    let by = (corner >> 1u) & 1u;
                    let bz = (corner >> 2u) & 1u;
                    let ix = u32(select(cx.x, cx.y, bx == 1u));
                    let iy = u32(select(cy.x, cy.y, by == 1u));
                    let iz = u32(select(cz.x, cz.y, bz == 1u));
                    let w = select(1.0 - cx.z, cx.z, bx == 1u) * select(1.0 - cy.z, cy.z, by == 1u)
                        * select(1.0 - cz.z, cz.z, bz == 1u);
                    let voxel_index = (iz * dims.y + iy) * dims.x + ix;
                    let base = voxel_index * n2;
                    if ms_n2 > 0u && params.view <= 1u {
                        acc_ms += w * field_at(voxel_index, cw);
                    }
                    if params.view == 3u {
                        acc.x += w * transfer[base];
                    } else {
                        for (var i = 0u; i < n2; i++) {
                            acc += w * transfer[base + i] * p[i];
                        }
                    }
                }
                if params.view == 3u {
                    sum += vec3<f32>(weight * acc.x * 0.5 / sqrt(PI));
                } else {
                    sum += weight * acc;
                    more += weight * acc_ms;
                }
            }
            if params.view != 1u && transmittance < 1e-4 {
                transmittance = 0.0;
                break;
            }
        }
    }
    var rgb = sum * params.albedo + more;
    if params.view == 2u {
        rgb = vec3<f32>(transmittance);
    } else if params.view == 3u {
        rgb = sum;
    }
    image[out_index] = vec4<f32>(rgb, 1.0);
}
