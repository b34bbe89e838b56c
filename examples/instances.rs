//! Writes the instancing stress case: a glTF file with `NODES` nodes (a 10 x 10 x 10 grid)
//! that all share one torus mesh of `MAJOR x MINOR x 2` triangles (100,000 by default), 100M
//! triangles as drawn and 2.4 MB of mesh data. Rendered, the mesh is stored once with one
//! bottom-level BVH and the nodes become instances under a top-level BVH; copied triangle by
//! triangle it would need about 30 GB.
//!
//! ```text
//! cargo run --release --features examples --example instances -- OUT_DIR [NODES_PER_SIDE [MAJOR MINOR]]
//! /usr/bin/time -v target/release/wavetrace render OUT_DIR/instances.gltf -o OUT_DIR/instances.png \
//!     --width 320 --height 240 --spp 4
//! ```

use std::path::PathBuf;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().unwrap_or_else(|| ".".to_string()));
    let side: usize = args.next().map_or(Ok(10), |a| a.parse())?;
    let major: u32 = args.next().map_or(Ok(250), |a| a.parse())?;
    let minor: u32 = args.next().map_or(Ok(200), |a| a.parse())?;
    std::fs::create_dir_all(&dir)?;

    // The torus around +Y (glTF's up), radii 1 and 0.35, with vertex normals.
    let tau = std::f32::consts::TAU;
    let (mut bytes, mut indices) = (Vec::<u8>::new(), Vec::<u32>::new());
    let mut normals = Vec::<u8>::new();
    for i in 0..major {
        let a = tau * i as f32 / major as f32;
        for j in 0..minor {
            let b = tau * j as f32 / minor as f32;
            let n = [a.cos() * b.cos(), b.sin(), a.sin() * b.cos()];
            let p = [a.cos() + 0.35 * n[0], 0.35 * n[1], a.sin() + 0.35 * n[2]];
            bytes.extend(p.iter().flat_map(|x| x.to_le_bytes()));
            normals.extend(n.iter().flat_map(|x| x.to_le_bytes()));
            let (i1, j1) = ((i + 1) % major, (j + 1) % minor);
            let v = |i: u32, j: u32| i * minor + j;
            indices.extend([v(i, j), v(i, j1), v(i1, j), v(i1, j), v(i, j1), v(i1, j1)]);
        }
    }
    let vertex_count = (major * minor) as usize;
    let positions_len = bytes.len();
    bytes.extend(&normals);
    let index_offset = bytes.len();
    bytes.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    std::fs::write(dir.join("instances.bin"), &bytes)?;

    // A grid of nodes, each turned a little differently, every one drawing mesh 0.
    let mut nodes = Vec::new();
    for x in 0..side {
        for y in 0..side {
            for z in 0..side {
                let angle = 0.37 * (x * 7 + y * 3 + z) as f32;
                let (s, c) = (angle * 0.5).sin_cos();
                nodes.push(format!(
                    r#"{{"mesh":0,"translation":[{},{},{}],"rotation":[{s},0,0,{c}]}}"#,
                    3.0 * x as f32,
                    3.0 * y as f32,
                    3.0 * z as f32
                ));
            }
        }
    }
    let roots: Vec<String> = (0..nodes.len()).map(|i| i.to_string()).collect();
    let json = format!(
        r#"{{"asset":{{"version":"2.0","generator":"wavetrace examples/instances.rs"}},
"scenes":[{{"nodes":[{roots}]}}],"nodes":[{nodes}],
"meshes":[{{"name":"torus","primitives":[{{"attributes":{{"POSITION":0,"NORMAL":1}},"indices":2}}]}}],
"buffers":[{{"byteLength":{len},"uri":"instances.bin"}}],
"bufferViews":[{{"buffer":0,"byteLength":{positions_len}}},
{{"buffer":0,"byteOffset":{positions_len},"byteLength":{positions_len}}},
{{"buffer":0,"byteOffset":{index_offset},"byteLength":{index_len}}}],
"accessors":[{{"bufferView":0,"componentType":5126,"count":{vertex_count},"type":"VEC3","min":[-1.35,-0.35,-1.35],"max":[1.35,0.35,1.35]}},
{{"bufferView":1,"componentType":5126,"count":{vertex_count},"type":"VEC3"}},
{{"bufferView":2,"componentType":5125,"count":{index_count},"type":"SCALAR"}}]}}"#,
        roots = roots.join(","),
        nodes = nodes.join(",\n"),
        len = bytes.len(),
        index_len = indices.len() * 4,
        index_count = indices.len(),
    );
    let path = dir.join("instances.gltf");
    std::fs::write(&path, json)?;
    println!(
        "{}: {} nodes sharing one mesh of {} triangles ({} drawn), {:.1} MB of mesh data",
        path.display(),
        side * side * side,
        indices.len() / 3,
        side * side * side * indices.len() / 3,
        bytes.len() as f64 / 1e6
    );
    Ok(())
}
