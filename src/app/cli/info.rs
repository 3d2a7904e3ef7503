//! `prt info`: what a transport or volume file holds, read from its header and small tables.

use super::*;

/// Prints what the metadata `m` of the transport file at `path` says of its bake.
pub(super) fn print_info(path: &std::path::Path, m: &crate::store::transport::TransportMeta) {
    let id = &m.identity;
    println!("file          {}", path.display());
    // Strings from the file are printed with their control characters escaped: a crafted
    // file must not drive the terminal.
    let printable = crate::files::printable;
    println!(
        "scene         {} (hash {})",
        printable(&m.scene_path),
        printable(&id.scene_hash)
    );
    if let (Some(pv), crate::store::transport::BakeDomain::Vertices { edge_length }) =
        (&m.per_vertex, id.domain)
    {
        println!(
            "vertices      {} vertices, {} triangles, {}edges up to {} (a row per vertex, any \
             camera; the file's camera is the scene's)",
            pv.vertices,
            pv.triangles,
            if id.refine_shadows {
                "refined at shadow borders from as many as "
            } else {
                ""
            },
            edge_length
        );
        if pv.albedo_maps > 0 {
            println!(
                "textures      {} albedo map(s): the textured vertices hold a white surface's \
                 light, which the raster multiplies by their map per pixel",
                pv.albedo_maps
            );
        }
        if id.visibility {
            print_gloss(path, m);
        }
    }
    // A per-vertex bake's rows are stored as an image of vertices: its size says nothing a user
    // asks for, and the camera's image size is the still's.
    let v = |p: [f32; 3]| format!("({:.3}, {:.3}, {:.3})", p[0], p[1], p[2]);
    let [width, height] = m
        .per_vertex
        .as_ref()
        .map_or([m.width, m.height], |pv| pv.image);
    println!(
        "camera        eye {}, target {}, up {}, fov_y_deg {}, {width} x {height}",
        v(m.camera.eye),
        v(m.camera.target),
        v(m.camera.up),
        m.camera.fov_y_deg
    );
    if m.per_vertex.is_none() {
        println!(
            "image         {} x {} ({} tiles of {}²)",
            m.width,
            m.height,
            {
                let (tx, ty) =
                    crate::store::transport::tile_grid(m.width as usize, m.height as usize);
                tx * ty
            },
            m.tile
        );
    }
    println!(
        "cube          N = {} ({} coefficients per row)",
        id.cube_n,
        6 * id.cube_n as usize * id.cube_n as usize
    );
    println!(
        "SH order      {} ({} coefficients per row)",
        id.sh_order,
        (id.sh_order as usize).pow(2)
    );
    let edges = if id.edge_spp > 0 {
        format!(" ({} at edges)", id.edge_spp)
    } else {
        String::new()
    };
    println!(
        "sampling      {} spp{edges}, {} samples/texel{}, seed {}{}",
        id.spp,
        id.texel_samples,
        if id.edge_texel_samples > 0 {
            format!(" ({} sub-texels where needed)", id.edge_texel_samples)
        } else {
            String::new()
        },
        id.seed,
        if id.unshadowed { ", unshadowed" } else { "" }
    );
    if id.bounces > 0 {
        let how = match &id.indirect {
            Some(i) if i.visibility == crate::bake::bounce::BounceVisibility::Cache => format!(
                "next-event rows, surface cache of {} points {} px apart",
                m.cache_points, i.cache_spacing
            ),
            Some(_) => "next-event rows, exact visibility".to_string(),
            None => "each path binned in the texel it leaves by (an older bake)".to_string(),
        };
        println!(
            "bounces       {} ({} paths per sample; {how})",
            id.bounces, id.paths
        );
    }
    print_storage(path, m);
}

/// The part of [`print_info`] that says what the bake kept and what it cost: sparsity, size,
/// energy dropped, rays; then its lights and its shard.
fn print_storage(path: &std::path::Path, m: &crate::store::transport::TransportMeta) {
    let (s, id) = (&m.stats, &m.identity);
    let bytes = std::fs::metadata(path).map(|x| x.len()).unwrap_or(0);
    let dense_bytes = s.dense_entries as f64 * 4.0;
    println!(
        "sparsify      threshold {} ({} budget, {} values)",
        id.threshold, id.budget, id.quantization
    );
    println!("rows          {}", s.rows);
    println!(
        "nonzeros      {} ({:.2}% of dense)",
        s.nonzeros,
        100.0 * s.nonzeros as f64 / s.dense_entries.max(1) as f64
    );
    let (count, unit) = match &m.per_vertex {
        Some(pv) => (pv.vertices as usize, "vertex"),
        None => (m.width as usize * m.height as usize, "pixel"),
    };
    println!(
        "size          {:.2} MiB file, {:.2}% of the dense f32 matrix, {:.1} bytes/{unit}",
        bytes as f64 / 1048576.0,
        100.0 * bytes as f64 / dense_bytes.max(1.0),
        bytes as f64 / count.max(1) as f64
    );
    println!(
        "dropped       {:.3}% of transport energy (relative L2 {:.3}%)",
        100.0 * s.dropped_energy_fraction,
        100.0 * s.dropped_energy_fraction.sqrt()
    );
    println!("shadow rays   {}", s.shadow_rays);
    for (i, l) in m.lights.iter().enumerate() {
        let label = if i == 0 { "lights" } else { "" };
        println!("{label:<14}{}", l.describe(id.light_samples));
    }
    if let Some([i, n]) = id.shard {
        println!("shard         {i}/{n} (join all {n} with `prt merge`)");
    }
}

pub(super) fn info(file: PathBuf) -> Result<()> {
    if crate::volume::is_volume_file(&file) {
        let v = crate::volume::VolumeTransfer::load(&file)?;
        let m = &v.meta;
        let [nx, ny, nz] = m.dims;
        println!("file          {} (volume transfer)", file.display());
        println!(
            "grid          {nx} x {ny} x {nz} voxels over {:?} to {:?}",
            m.min, m.max
        );
        println!(
            "medium        extinction {}, albedo {:?}, g {}",
            m.extinction, m.albedo, m.g
        );
        println!(
            "transfer      SH order {} ({} coefficients per voxel), {} directions",
            m.sh_order,
            v.sh_count(),
            m.directions
        );
        println!(
            "default view  eye {:?}, target {:?}, {} x {}",
            m.camera.eye, m.camera.target, m.width, m.height
        );
        return Ok(());
    }
    // The header holds everything printed; the small tables are read and checked, the entries
    // and values are not.
    let meta = crate::store::transport::read_summary(&file)?;
    print_info(&file, &meta);
    Ok(())
}

/// The line of a glossy per-vertex bake with visibility: what its glossy vertices keep, and
/// whether its local lights' highlights are drawn.
fn print_gloss(path: &std::path::Path, m: &crate::store::transport::TransportMeta) {
    let bits = 4 * crate::scene::visibility::Visibility::words(m.identity.cube_n as usize);
    let columns = m.light_columns();
    let version = crate::store::transport::read_format_version(path).unwrap_or(0);
    let kept = format!("each glossy vertex keeps the cube texels it sees ({bits} bytes)");
    let line = match columns {
        0 => format!("{kept}: its lobe is drawn per pixel"),
        _ if version < 10 => format!(
            "{kept}: its lobe is drawn per pixel; no share of its {columns} light column(s) \
             (format version {version}): their highlights are not drawn until it is baked again"
        ),
        _ => format!(
            "{kept} and its share of each of the {columns} light column(s) ({} bytes): its lobe \
             and the lights' highlights are drawn per pixel",
            4 * columns
        ),
    };
    println!("gloss         {line}");
}
