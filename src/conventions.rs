//! The numeric conventions of the engine, fixed once. Every other module links here instead of
//! restating them.
//!
//! # World and camera
//! Right-handed world, **+Y up**. Angles are degrees in files and on the command line, radians in
//! code. Pinhole camera (`eye`, `target`, `up`, `fov_y_deg`, `width` x `height`); pixel (x, y) has y
//! growing downwards and its centre at ((x + 0.5) / width, (y + 0.5) / height) of the film. With one
//! sample per pixel the primary ray goes through the pixel centre.
//!
//! # Environment maps (lat-long)
//! Linear RGB radiance. Pixel (x, y) of a W x H map has u = (x + 0.5) / W, v = (y + 0.5) / H and
//! direction `d(u, v) = (sin 2πu · sin πv, cos πv, −cos 2πu · sin πv)`: row 0 is the zenith (+Y),
//! u = 0 looks along −Z, u = 0.25 along +X (Mitsuba 3's `envmap` convention). A map is piecewise
//! constant over its cells `[x/W, (x+1)/W) × [y/H, (y+1)/H)`; row y subtends
//! `(2π / W)(cos(πy/H) − cos(π(y+1)/H))` per pixel. Rotating by `yaw` turns the environment about +Y
//! by the right-hand rule: world direction = R_y(yaw) · map direction. Pitch (an extension) turns it
//! about +X afterwards: world = R_x(pitch) · R_y(yaw) · map.
//!
//! # Surfaces
//! Two-sided: either side sees the same material, the normal flipped towards the incoming ray. Meshes
//! use their `vn` normals when the OBJ has them, else geometric normals, unless `smooth_normals`.
//!
//! # Cube maps
//! Faces **+X, −X, +Y, −Y, +Z, −Z** (0..5), N x N texels each, N a power of two. Texel (row, col) has
//! s = (2 col + 1)/N − 1, t = (2 row + 1)/N − 1 and unnormalised direction
//! `+X: (1, −t, −s)  −X: (−1, −t, s)  +Y: (s, 1, t)  −Y: (s, −1, −t)  +Z: (s, −t, 1)  −Z: (−s, −t, −1)`
//! (the OpenGL / Vulkan / wgpu convention). Linear texel index: `face·N² + row·N + col`. Texel solid
//! angles are exact (corner formula `atan2(ab, sqrt(a² + b² + 1))`) and sum to 4π. A texel light holds
//! the **average** radiance over its solid angle (area resampling, see [`crate::math::cubemap`]).
//!
//! # Light vector and transport
//! Texel light j carries radiance L_j. Outgoing radiance at pixel p is `Σ_j T[p][j] L_j`, where `T[p][j]`
//! integrates visibility × BRDF × cosine over texel j's solid angle, so T contains the solid angle
//! and L is a radiance. Relighting with every term reproduces the brute-force render exactly.
//!
//! # Haar wavelets
//! Orthonormal **non-standard** 2-D Haar transform of each face on its own, down to one scaling
//! coefficient per face (6 N² coefficients, Parseval exact). Light and transport rows use the same
//! basis, so `T l = (T Wᵀ)(W l)`. Coefficient layout inside a face is given in [`crate::math::haar`].
//!
//! # Spherical harmonics
//! Real SH, index `i = l(l + 1) + m`, orthonormal, Condon–Shortley phase included, evaluated on the
//! world direction (x, y, z) with **+z as the polar axis**: Y₀⁰ = 0.282095, Y₁⁻¹ = −0.488603 y,
//! Y₁⁰ = 0.488603 z, Y₁¹ = −0.488603 x, ... "Order n" means bands l = 0..n−1, n² coefficients.
//! Environment coefficients are plain projections of radiance, `L_i = ∫ L(ω) Y_i(ω) dω`; cosine,
//! visibility, BRDF and phase belong to the transfer. The clamped cosine about +z projects to
//! (0.886227, 0, 1.02333, 0, 0, 0, 0.495416, 0, 0).
//!
//! # Volumes
//! Extinction σ_t per unit length, single-scattering albedo, Henyey–Greenstein phase with g
//! (g = 0 isotropic, 1/(4π)). Transmittance `exp(−∫σ_t)`. SH self-transfer `T_i(x) = ∫ τ(x, ω) Y_i(ω) dω`.
//!
//! # Error metrics
//! Relative L2 of image A against reference R: `‖A − R‖₂ / ‖R‖₂` over every channel of the pixels that
//! see geometry; RMSE and PSNR beside it. Images show the environment behind the scene in the pixels
//! (or the parts of pixels) that see none, turned with the light ([`crate::draw::background`]); metrics
//! are taken before it is added.
