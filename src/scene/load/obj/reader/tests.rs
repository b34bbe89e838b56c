//! The reader's unit tests: statements, indices, runs, smoothing groups and the errors
//! and warnings of bad files.

use super::*;

/// Reads `text` as `m.obj` (no material library can load), with its warnings.
fn read_text(text: &str) -> Result<(Obj, Vec<String>)> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.obj");
    std::fs::write(&path, text).unwrap();
    let mut warnings = Vec::new();
    let obj = read(
        &path,
        |_| Err(tobj::LoadError::OpenFileFailed),
        &mut warnings,
    )?;
    // Warnings name the file by its full path: keep the name only.
    let prefix = format!("{}: ", path.display());
    let warnings = warnings
        .iter()
        .map(|w| w.replace(&prefix, "m.obj: "))
        .collect();
    Ok((obj, warnings))
}

fn error(text: &str) -> String {
    match read_text(text) {
        Ok(_) => panic!("{text:?} loaded"),
        Err(e) => e.to_string(),
    }
}

const SQUARE: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                      vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nvn 0 0 -1\n";

#[test]
fn indices_of_every_form_name_the_same_vertices() {
    // Positive, negative (relative to the lines above), and the forms v/vt, v//vn, v/vt/vn.
    for face in [
        "f 1/1/1 2/2/1 3/3/1",
        "f -4/-4/-2 -3/-3/-2 -2/-2/-2",
        "f 1/1/1 -3/2/-2 3/-2/1",
    ] {
        let (obj, warnings) = read_text(&format!("{SQUARE}{face}\n")).unwrap();
        assert!(warnings.is_empty(), "{warnings:?}");
        let mesh = &obj.runs[0].mesh;
        assert_eq!(mesh.indices, [[0, 1, 2]], "{face}");
        assert_eq!(
            mesh.positions,
            [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0)]
        );
        // v is flipped: OBJ's runs up the image.
        let uvs = [
            Vec2::new(0.0, 1.0),
            Vec2::new(1.0, 1.0),
            Vec2::new(1.0, 0.0),
        ];
        assert_eq!(mesh.uvs, uvs, "{face}");
        assert_eq!(mesh.normals, [Vec3::Z; 3], "{face}");
    }
    let (obj, _) = read_text(&format!("{SQUARE}f 1//2 2//2 3//2\n")).unwrap();
    let mesh = &obj.runs[0].mesh;
    assert_eq!((mesh.normals.len(), mesh.uvs.len()), (3, 0));
    assert_eq!(mesh.normals[0], Vec3::NEG_Z);
    let (obj, _) = read_text(&format!("{SQUARE}f 1/4 2/3 3/2\n")).unwrap();
    let mesh = &obj.runs[0].mesh;
    assert_eq!((mesh.normals.len(), mesh.uvs.len()), (0, 3));
    assert_eq!(mesh.uvs[0], Vec2::new(0.0, 0.0));
}

#[test]
fn vertices_are_shared_within_a_run_and_split_by_their_attributes() {
    // A quad of two triangles sharing two positions: 4 vertices, in order of first use.
    let (obj, _) = read_text(&format!("{SQUARE}f 3 1 2\nf 1 3 4\n")).unwrap();
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.indices, [[0, 1, 2], [1, 0, 3]]);
    assert_eq!(mesh.positions[0], Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(mesh.positions.len(), 4);
    // The same position with two normals is two vertices; a corner without vt or vn
    // after some with them is a vertex of its own, and the run keeps no partial column.
    let (obj, _) = read_text(&format!("{SQUARE}f 1 2 3\nf 1//1 3//2 4//1\n")).unwrap();
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.indices, [[0, 1, 2], [3, 4, 5]]);
    assert_eq!(mesh.positions.len(), 6);
    assert!(mesh.normals.is_empty(), "vertices 0 to 2 have no normal");
    let (obj, _) = read_text(&format!("{SQUARE}f 1//1 2//1 3//1\nf 1//1 3//1 4//2\n")).unwrap();
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.indices, [[0, 1, 2], [0, 2, 3]]);
    assert_eq!(mesh.normals[3], Vec3::NEG_Z);
}

#[test]
fn objects_groups_and_materials_make_runs_with_their_own_vertices() {
    let text = format!(
        "{SQUARE}usemtl red\nf 1 2 3\ng wall\nf 3 4 1\nusemtl blue\nusemtl red\nf 4 1 2\n\
         usemtl blue\nf 4 2 3\no\ng floor  tiles \no empty\n"
    );
    let (obj, warnings) = read_text(&text).unwrap();
    let runs: Vec<(&str, usize, usize)> = obj
        .runs
        .iter()
        .map(|r| {
            (
                r.name.as_str(),
                r.mesh.positions.len(),
                r.mesh.indices.len(),
            )
        })
        .collect();
    // `usemtl` names no known material here (no library): every run has `None`, so a
    // change of name splits nothing; `g wall` does. A run without faces is no entity.
    assert_eq!(runs, [("unnamed_object", 3, 1), ("wall", 4, 3)]);
    assert!(obj.runs.iter().all(|r| r.material.is_none()));
    // Run-local vertices: `wall` numbers its own from 0 in order of first use.
    assert_eq!(obj.runs[1].mesh.indices, [[0, 1, 2], [1, 2, 3], [1, 3, 0]]);
    assert_eq!(obj.runs[1].mesh.positions[0], Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(
        warnings,
        [
            "m.obj: line 11: usemtl names a material but the file loads no material library \
          (mtllib); using a default grey"
        ]
    );
    // A file without faces is one empty run (tobj's behaviour), not an error here.
    let (obj, _) = read_text("v 0 0 0\n").unwrap();
    assert_eq!(obj.runs.len(), 1);
    assert!(obj.runs[0].mesh.indices.is_empty());
}

#[test]
fn materials_split_runs_when_they_change() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.obj");
    std::fs::write(
        &path,
        format!(
            "mtllib a.mtl\n{SQUARE}f 1 2 3\nusemtl red\nusemtl red\nf 1 2 3\n\
             usemtl blue\nusemtl gone\nf 1 2 3\ng x\nusemtl blue\nf 1 2 3\n"
        ),
    )
    .unwrap();
    let library = "newmtl red\nKd 1 0 0\nnewmtl blue\nKd 0 0 1\n";
    let mut warnings = Vec::new();
    let obj = read(
        &path,
        |p| {
            assert_eq!(p, dir.path().join("a.mtl"));
            tobj::load_mtl_buf(&mut library.as_bytes())
        },
        &mut warnings,
    )
    .unwrap();
    let runs: Vec<(&str, Option<usize>)> = obj
        .runs
        .iter()
        .map(|r| (r.name.as_str(), r.material))
        .collect();
    assert_eq!(
        runs,
        [
            ("unnamed_object", None),
            ("unnamed_object", Some(0)),
            ("unnamed_object", None),
            ("x", Some(1)),
        ]
    );
    assert_eq!(obj.materials.len(), 2);
    assert!(warnings.is_empty(), "{warnings:?}");
}

/// A roof: two unit squares meeting at a right angle along the edge x = 0 (vertices 1, 2),
/// one sloping down to +x, one to -x, with `head` before the first face and `middle`
/// between the two.
fn roof(head: &str, middle: &str) -> Obj {
    let text = format!(
        "v 0 0 1\nv 0 1 1\nv 1 0 0\nv 1 1 0\nv -1 0 0\nv -1 1 0\n\
         {head}f 1 3 4 2\n{middle}f 1 2 6 5\n"
    );
    let (obj, warnings) = read_text(&text).unwrap();
    assert!(warnings.is_empty(), "{warnings:?}");
    obj
}

#[test]
fn smoothing_groups_give_faces_without_normals_smooth_vertex_normals() {
    // Without `s` (or with `s off`) the faces shade flat: no normal column.
    for head in ["", "s off\n", "s 0\n"] {
        let obj = roof(head, "");
        assert!(obj.runs[0].mesh.normals.is_empty(), "{head:?}");
        assert_eq!(obj.runs[0].mesh.positions.len(), 6);
    }
    // One group: the ridge's two vertices are shared and take the mean normal, straight
    // up; each eave keeps its own face's normal. The squares' two triangles each would
    // count twice at a corner where the square is cut, once elsewhere, if the triangles
    // were weighted alike: the angles weigh them as the square's one face.
    let obj = roof("s 1\n", "");
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.positions.len(), 6);
    let h = std::f32::consts::FRAC_1_SQRT_2;
    // The smooth roof's normal at a vertex: up on the ridge, the slope's at the eaves.
    let smooth = |position: &Vec3| match position.x {
        0.0 => Vec3::Z,
        x if x > 0.0 => Vec3::new(h, 0.0, h),
        _ => Vec3::new(-h, 0.0, h),
    };
    for (position, normal) in mesh.positions.iter().zip(&mesh.normals) {
        let expected = smooth(position);
        assert!(
            (*normal - expected).length() < 1e-6,
            "{position}: {normal} against {expected}"
        );
    }
    // Two groups: the ridge is a crease, its vertices split, each with its face's normal.
    let obj = roof("s 1\n", "s 2\n");
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.positions.len(), 8);
    for (k, normal) in mesh.normals.iter().enumerate() {
        let side = if k < 4 { h } else { -h };
        assert!(
            (*normal - Vec3::new(side, 0.0, h)).length() < 1e-6,
            "{k}: {normal}"
        );
    }
    // A group and a flat face: the flat face's own vertices have no normal (zero: the
    // flattening shades their triangles flat); the ridge splits.
    let obj = roof("s 1\n", "s off\n");
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.positions.len(), 8);
    assert!(
        mesh.normals[..4]
            .iter()
            .all(|n| (*n - Vec3::new(h, 0.0, h)).length() < 1e-6)
    );
    assert!(mesh.normals[4..].iter().all(|n| *n == Vec3::ZERO));
    // A two-sided roof (each face again with the opposite winding, sharing its
    // vertices): the normals cancel, and the sheet's normal is taken up to its sign.
    let obj = roof("s 1\nf 2 4 3 1\n", "f 5 6 2 1\n");
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.positions.len(), 6);
    for (position, normal) in mesh.positions.iter().zip(&mesh.normals) {
        let expected = smooth(position);
        assert!(
            (normal.dot(expected).abs() - 1.0).abs() < 1e-6,
            "{position}: {normal} against {expected}"
        );
    }
    // Faces with their own normals keep them whatever the group.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 1 0\ns 1\nf 1//1 2//1 3//1\n";
    let (obj, _) = read_text(text).unwrap();
    assert_eq!(obj.runs[0].mesh.normals, [Vec3::Y; 3]);
}

#[test]
fn statements_not_read_are_named_in_one_warning() {
    let text = "# a comment\ncstype bspline\ndeg 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n\
                curv 0 1 1 2 3\nmg 1\nf 1 2 3\nbevel off\ncurv 0 1 3 2 1\n";
    let (obj, warnings) = read_text(text).unwrap();
    assert_eq!(obj.runs[0].mesh.indices.len(), 1);
    assert_eq!(
        warnings,
        [
            "m.obj: statements wavetrace does not read are ignored: bevel (1, first at line \
          10), cstype (1, first at line 2), curv (2, first at line 7), deg (1, first at \
          line 3)"
        ]
    );
}

#[test]
fn mtllib_reads_a_name_with_spaces_if_that_file_exists_else_each_name() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.obj");
    std::fs::write(dir.path().join("my lib.mtl"), "").unwrap();
    let libraries = |statement: &str| {
        std::fs::write(&path, format!("{statement}\n{SQUARE}f 1 2 3\n")).unwrap();
        let mut asked = Vec::new();
        read(
            &path,
            |p| {
                asked.push(p.file_name().unwrap().to_string_lossy().into_owned());
                tobj::load_mtl_buf(&mut "".as_bytes())
            },
            &mut Vec::new(),
        )
        .unwrap();
        asked
    };
    assert_eq!(libraries("mtllib my lib.mtl"), ["my lib.mtl"]);
    assert_eq!(libraries("mtllib a.mtl  b.mtl"), ["a.mtl", "b.mtl"]);
    assert_eq!(libraries("mtllib one.mtl"), ["one.mtl"]);
}

#[test]
fn continuations_lines_points_and_short_faces_with_one_warning_each() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 \\\n 3\nl 1 2 3\nl 2 3\n\
                f 1 2\np 1\nf\nf 2 \\\n4 \\\n  3\nf 1 2 bad\n";
    let (_, warnings) = read_text(text).unwrap();
    assert_eq!(
        warnings.last().unwrap(),
        "m.obj: faces with a bad index are skipped (1, first at line 15: face: 'bad' in \
         'bad' is not an index)"
    );
    let text = text.replace("f 1 2 bad\n", "");
    let (obj, warnings) = read_text(&text).unwrap();
    assert_eq!(obj.runs[0].mesh.indices, [[0, 1, 2], [1, 3, 2]]);
    assert_eq!(
        warnings,
        [
            "m.obj: line elements (l) are not rendered (2, first at line 7)",
            "m.obj: point elements (p) are not rendered (1, first at line 10)",
            "m.obj: faces with fewer than 3 vertices are skipped (2, first at line 9)",
        ]
    );
}

#[test]
fn polygons_are_cut_into_ears_also_when_they_refer_forward() {
    // An L shape (area 3), once with its vertices above, once with them below the face.
    let vertices = "v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\n";
    let face = "f 1 2 3 4 5 6\n";
    let (above, _) = read_text(&format!("{vertices}{face}")).unwrap();
    let (below, _) = read_text(&format!("{face}{vertices}")).unwrap();
    let mut expected = Vec::new();
    let polygon: Vec<u32> = (0..6).collect();
    let positions = &above.runs[0].mesh.positions;
    super::super::polygons::triangulate_polygon(positions, &polygon, &mut expected).unwrap();
    assert_eq!(expected.len(), 4);
    assert_eq!(above.runs[0].mesh.indices, expected);
    assert_eq!(below.runs[0].mesh.indices, expected);
    assert_eq!(below.runs[0].mesh.positions, *positions);
    // A forward triangle, and one past the end of the file.
    let (obj, _) = read_text("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    assert_eq!(obj.runs[0].mesh.positions[2], Vec3::Y);
    let (obj, warnings) = read_text("f 1 2 4\nf 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    assert_eq!(obj.runs[0].mesh.indices.len(), 1);
    assert_eq!(obj.runs[0].mesh.positions.len(), 3);
    assert_eq!(
        warnings,
        [
            "m.obj: faces naming a vertex past the file's last are skipped (1 triangle; line 1 \
          names vertex 4, and the file has 3 vertices)"
        ]
    );
}

/// One bad face is skipped with a warning naming the first; a texture coordinate or
/// normal index past the file's last drops that column from its object (trimesh's
/// `cubevt.obj` names `vt` it does not have); a nameless `usemtl` (Rhino's
/// `wallhole.obj`) takes the default material.
#[test]
fn bad_indices_skip_their_faces_and_name_line_and_value() {
    let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\n";
    let good = "f 1 2 3\n";
    let skipped = |f: &str| {
        let (obj, warnings) = read_text(&format!("{v}{good}{f}\n")).unwrap();
        let triangles: Vec<usize> = obj.runs.iter().map(|r| r.mesh.indices.len()).collect();
        assert_eq!(triangles, [1], "{f}: {warnings:?}");
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        warnings[0].clone()
    };
    let w = skipped("f 0 1 2");
    assert!(
        w.starts_with("m.obj: faces with a bad index are skipped (1, first at line 7: face: vertex index 0 in '0' is invalid"),
        "{w}"
    );
    let w = skipped("f 1 2 5");
    assert_eq!(
        w,
        "m.obj: faces naming a vertex past the file's last are skipped (1 triangle; line 7 \
         names vertex 5, and the file has 4 vertices)"
    );
    let w = skipped("f 2 3 4 9");
    assert!(w.contains("(2 triangles; line 7 names vertex 9"), "{w}");
    let w = skipped("f -1 -2 -5");
    assert!(w.contains("relative vertex index -5 in '-5' reaches before the first vertex (4 defined above this line)"), "{w}");
    let w = skipped("f 1/-2147483648 2/1 3/1");
    assert!(
        w.contains("relative texture coordinate index -2147483648"),
        "{w}"
    );
    let w = skipped("f 1/1/1/1 2 3");
    assert!(w.contains("more than three"), "{w}");
    let w = skipped("f /1 2 3");
    assert!(w.contains("face: '' in '/1' is not an index"), "{w}");
    // Two bad faces: one warning that counts them.
    let (_, warnings) = read_text(&format!("{v}{good}f 0 1 2\nf x 1 2\n")).unwrap();
    assert_eq!(warnings.len(), 1);
    assert!(
        warnings[0].contains("skipped (2, first at line 7"),
        "{warnings:?}"
    );

    // Attribute indices past the last: the face stays, its object loses the column.
    let (obj, warnings) = read_text(&format!("{v}f 1/1/1 2/1/1 3/1/1\n")).unwrap();
    let mesh = &obj.runs[0].mesh;
    assert_eq!(mesh.indices.len(), 1);
    assert!(mesh.normals.is_empty());
    assert_eq!(mesh.uvs.len(), 3, "the texture coordinates are kept");
    assert_eq!(
        warnings,
        [
            "m.obj: normal indices past the file's last are ignored (line 6 names normal 1, \
          and the file has 0 normals); the objects that name one render with the \
          triangles' own normals"
        ]
    );
    let (obj, warnings) = read_text(&format!("{v}f 1/2 2/1 3/99999999999\n")).unwrap();
    assert!(obj.runs[0].mesh.uvs.is_empty());
    assert_eq!(warnings.len(), 1);
    assert!(
        warnings[0].contains("texture coordinate indices past the file's last are ignored (line 6 names texture coordinate 99999999999, and the file has 1 texture coordinate)"),
        "{warnings:?}"
    );

    // A nameless usemtl.
    let (obj, warnings) = read_text(&format!("usemtl \n{v}{good}")).unwrap();
    assert_eq!(obj.runs[0].material, None);
    assert_eq!(
        warnings,
        ["m.obj: line 1: usemtl without a material name; its faces use a default grey"]
    );
}

#[test]
fn bad_numbers_name_line_and_value() {
    let e = error("v 0 0 0\nv 1 x 0\n");
    assert!(e.ends_with(":line 2: vertex: 'x' is not a number"), "{e}");
    let e = error("v 0 0 0\nvt 0\n");
    assert!(
        e.ends_with(":line 2: texture coordinate: 2 numbers needed, found 1"),
        "{e}"
    );
    let e = error("vn 0 0\n");
    assert!(
        e.ends_with(":line 1: normal: 3 numbers needed, found 2"),
        "{e}"
    );
    let e = error("v 1 2 3 0\n");
    assert!(
        e.ends_with(":line 1: vertex: w is 0 (positions are divided by w)"),
        "{e}"
    );
    let e = error("v 1 2 3 4 5\n");
    assert!(e.contains("found 5 numbers"), "{e}");
    let e = error("v 1 2 3 0.5 0.5 red\n");
    assert!(e.ends_with("vertex: 'red' is not a number"), "{e}");
    // Non-finite vertices are refused where a face uses them, naming their line.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1e39 0\nv nan 0 0\nf 1 2 3\n";
    let e = error(text);
    assert!(
        e.ends_with(":line 3: vertex (0, inf, 0) is not finite"),
        "{e}"
    );
    assert!(read_text(&text.replace("f 1 2 3", "f 1 2 -1")).is_err());
    assert!(
        read_text(&text.replace("f 1 2 3", "f 1 2 1")).is_ok(),
        "unused: no error"
    );
    // `w` divides.
    let (obj, _) = read_text("v 2 4 6 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert_eq!(obj.runs[0].mesh.positions[0], Vec3::new(1.0, 2.0, 3.0));
    assert!(error("  \n\n").ends_with("file is empty"));
    let e = error("v 0 0 0\nv \u{0}\u{ff}");
    assert!(e.contains("line 2"), "{e}");
}

#[test]
fn vertex_colours_where_some_vertices_have_none_are_white() {
    let text = "v 0 0 0\nv 1 0 0 1 0 0\nv 0 1 0 0 2 0\nv 1 1 0\nf 1 2 3\nf 4 3 2\n";
    let (obj, warnings) = read_text(text).unwrap();
    let colors = obj.runs[0].colors.as_ref().unwrap();
    let expected = [Vec3::ONE, Vec3::X, Vec3::Y, Vec3::ONE].map(|c| c.extend(1.0));
    assert_eq!(colors, &expected, "clamped to [0, 1]");
    assert_eq!(
        warnings,
        [
            "m.obj: some vertices have colours (v x y z r g b) and others not; those without \
          are white"
        ]
    );
    let (obj, _) = read_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert!(obj.runs[0].colors.is_none());
}
