//! Library and material names: `polarid library --list` prints a library's materials with
//! their category, bands and surface layer; a mistyped library name (`--library bultin`)
//! or material name (`Gold (Au)` in a scene) exits 2 with the nearest names; `polarid
//! library` writes the materials' native surface layers (docs/MATERIALS.md).

use crate::common;

use common::{polarid, polarid_in, text};

use std::path::PathBuf;
use std::process::Output;

use polarid_io::library::Library;

fn data() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../data"))
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "stderr: {}", text(&o.stderr));
    text(&o.stdout)
}

/// Exit status 2, nothing on standard output, every word in the message.
fn bad(o: &Output, words: &[&str]) {
    let e = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {e}");
    assert!(o.stdout.is_empty(), "stdout: {}", text(&o.stdout));
    for w in words {
        assert!(e.contains(w), "{w:?} not in: {e}");
    }
}

#[test]
fn list_prints_names_categories_bands_and_layers() {
    let out = ok(&polarid(&["library", "--list"]));
    assert!(
        out.starts_with("# library builtin: 39 materials\n"),
        "{out}"
    );
    let line = |name: &str| {
        out.lines()
            .find(|l| l.split_whitespace().next() == Some(name))
            .unwrap_or_else(|| panic!("{name} not in {out}"))
            .split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
    };
    assert_eq!(line("aluminum"), "aluminum metal 650 Al2O3 2–5 nm");
    assert_eq!(line("gold"), "gold metal 650 contamination 0.5–1.5 nm");
    assert_eq!(line("N-BK7"), "N-BK7 dielectric 650 contamination 0–2 nm");
    let out = ok(&polarid(&["library", "--list", "builtin-rgb"]));
    assert!(
        out.contains("copper") && out.contains("450,550,650"),
        "{out}"
    );
    let out = ok(&polarid(&["library", "--list", "paper2007"]));
    assert!(
        out.starts_with("# library paper2007: 3 materials\n"),
        "{out}"
    );
    assert!(out.contains("green_paint"), "{out}");
    // A library file, without layers.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("lib.csv"), "name,n,k\nfoo,1.5,0\n").unwrap();
    let out = ok(&polarid_in(dir.path(), &["library", "--list", "lib.csv"]));
    assert!(
        out.lines()
            .any(|l| l.split_whitespace().collect::<Vec<_>>() == ["foo", "-", "-", "-"]),
        "{out}"
    );
}

#[test]
fn mistyped_library_names_get_suggestions() {
    bad(
        &polarid(&["library", "--list", "bultin"]),
        &["bultin", "did you mean `builtin`?"],
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("fits.csv"),
        "target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\nA,,1.5,0.1,,,,,3,ok\n",
    )
    .unwrap();
    let o = polarid_in(
        dir.path(),
        &[
            "classify",
            "fits.csv",
            "--library",
            "bultin",
            "-o",
            "out.csv",
        ],
    );
    bad(&o, &["bultin", "did you mean `builtin`?"]);
    assert!(!dir.path().join("out.csv").exists());
    let o = polarid_in(
        dir.path(),
        &[
            "classify",
            "fits.csv",
            "--library",
            "builtin_rgb",
            "-o",
            "out.csv",
        ],
    );
    bad(&o, &["did you mean `builtin-rgb`"]);
}

#[test]
fn mistyped_material_names_get_suggestions() {
    let scene = r#"name = "names"
width = 64
height = 32
theta_r_deg = 60
theta_i_deg = [40, 55, 70]
seed = 4
bands = { R = 650.0, G = 550.0, B = 450.0 }

[capture]
kind = "dofp"
color = "RGGB"

[[plate]]
name = "au"
material = "Gold (Au)"
sigma = 0.2
rect = [0, 0, 32, 32]
"#;
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), scene).unwrap();
    let o = polarid_in(dir.path(), &["simulate", "scene.toml", "-o", "out"]);
    bad(
        &o,
        &[
            "plate[1].material",
            "\"Gold (Au)\"",
            "builtin-rgb",
            "did you mean `gold`?",
            "polarid library --list builtin-rgb",
        ],
    );
    assert!(!dir.path().join("out").exists());
}

#[test]
fn library_writes_the_surfaces_of_builtin_materials() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let db = data().join("materials").join("refractiveindex");
    let files: Vec<String> = [
        "main/Al/nk/Rakic.yml",
        "main/Cu/nk/Johnson.yml",
        "main/Si/nk/Aspnes.yml",
    ]
    .iter()
    .map(|f| db.join(f).display().to_string())
    .collect();
    // Default names (Al_Rakic ...): the surfaces of the built-in materials' files.
    let mut args = vec!["library"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--band", "610:690", "-o", "lib.csv"]);
    ok(&polarid_in(d, &args));
    let lib = Library::read_csv(&d.join("lib.csv")).unwrap();
    let builtin = Library::builtin().unwrap();
    for (ours, theirs) in [
        ("Al_Rakic", "aluminum"),
        ("Cu_Johnson", "copper"),
        ("Si_Aspnes", "silicon"),
    ] {
        let a = lib.materials.iter().find(|m| m.name == ours).unwrap();
        let b = builtin.materials.iter().find(|m| m.name == theirs).unwrap();
        let (la, lb) = (a.layer.as_ref().unwrap(), b.layer.as_ref().unwrap());
        assert_eq!(
            (&la.name, la.min_nm, la.max_nm),
            (&lb.name, lb.min_nm, lb.max_nm)
        );
        // Same band, same method: the same layer index as the built-in library's.
        let (x, y) = (la.index.unwrap(), lb.index.unwrap());
        assert!(
            (x.0 - y.0).abs() < 1e-12 && (x.1 - y.1).abs() < 1e-12,
            "{ours}: {x:?} {y:?}"
        );
    }
    // A names map with its own layers: a constant index, `none`, and a bad range.
    std::fs::write(
        d.join("names.csv"),
        "file,name,layer,layer_min_nm,layer_max_nm,layer_n,layer_k\n\
         Al/nk/Rakic.yml,al,my_oxide,1,4,1.7,0.01\n\
         Cu/nk/Johnson.yml,cu,none,,,,\n",
    )
    .unwrap();
    let mut args = vec!["library"];
    args.extend(files.iter().map(String::as_str));
    args.extend([
        "--band",
        "450",
        "--band",
        "650",
        "--names",
        "names.csv",
        "-o",
        "map.csv",
    ]);
    ok(&polarid_in(d, &args));
    let lib = Library::read_csv(&d.join("map.csv")).unwrap();
    let al: Vec<_> = lib.materials.iter().filter(|m| m.name == "al").collect();
    assert_eq!(al.len(), 2);
    for m in al {
        let l = m.layer.as_ref().unwrap();
        assert_eq!(
            (l.name.as_str(), l.index, l.min_nm, l.max_nm),
            ("my_oxide", Some((1.7, 0.01)), 1.0, 4.0)
        );
    }
    assert!(
        lib.materials
            .iter()
            .filter(|m| m.name == "cu")
            .all(|m| m.layer.is_none())
    );
    let si: Vec<_> = lib
        .materials
        .iter()
        .filter(|m| m.name == "Si_Aspnes")
        .collect();
    let n: Vec<f64> = si
        .iter()
        .map(|m| m.layer.as_ref().unwrap().index.unwrap().0)
        .collect();
    assert!(n[0] > n[1], "SiO2 is dispersive: {n:?}");
    // Bad layer values exit 2 naming the map, the line, the column and the value.
    std::fs::write(
        d.join("bad.csv"),
        "file,name,layer,layer_min_nm,layer_max_nm\nAl/nk/Rakic.yml,al,Al2O3,5,2\n",
    )
    .unwrap();
    let mut args = vec!["library"];
    args.extend(files.iter().map(String::as_str));
    args.extend(["--band", "650", "--names", "bad.csv", "-o", "bad_out.csv"]);
    bad(
        &polarid_in(d, &args),
        &["bad.csv", "line 2", "layer_max_nm", "\"2\""],
    );
    std::fs::write(
        d.join("bad2.csv"),
        "file,name,layer,layer_min_nm,layer_max_nm\nAl/nk/Rakic.yml,al,Al2O4,2,5\n",
    )
    .unwrap();
    args.pop();
    args.pop();
    args.pop();
    args.extend(["bad2.csv", "-o", "bad_out.csv"]);
    bad(
        &polarid_in(d, &args),
        &[
            "bad2.csv",
            "line 2",
            "`layer`",
            "\"Al2O4\"",
            "unknown layer material",
        ],
    );
    assert!(!d.join("bad_out.csv").exists());
}
