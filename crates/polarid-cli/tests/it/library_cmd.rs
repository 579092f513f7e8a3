//! `polarid library`: building a material library CSV for a band from the
//! refractiveindex.info YAML files of `data/materials/` — the built-in 650 nm library reproduced, a 532 nm
//! library checked against hand-interpolated database values, the output used by
//! `polarid classify --library`, and bad inputs (exit status 2, file/field/value in the
//! message, no output left behind).

use crate::common;

use common::{polarid_in, text};

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

use polarid_io::library::Library;
use polarid_io::table::CsvTable;

/// The repository's reference data folder (`data/`).
fn data() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../data"))
}

fn db() -> PathBuf {
    data().join("materials").join("refractiveindex")
}

fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "status {:?}\nstderr: {}",
        o.status,
        text(&o.stderr)
    );
}

/// Exit status 2, the message contains every word of `words`; returns the message.
fn bad(o: &Output, words: &[&str]) -> String {
    let e = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "stderr: {e}");
    for w in words {
        assert!(e.contains(w), "{w:?} not in: {e}");
    }
    assert!(o.stdout.is_empty(), "stdout: {}", text(&o.stdout));
    e
}

/// The entries of a directory (non-recursive), sorted.
fn listing(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

fn material<'a>(lib: &'a Library, name: &str) -> &'a polarid_io::library::Material {
    lib.materials
        .iter()
        .find(|m| m.name == name)
        .unwrap_or_else(|| panic!("no material {name} in {}", lib.source))
}

/// `db_path` of the built-in CSV → YAML file of the database copy (as in
/// polarid-io/tests/it/library_yaml.rs; the CSV uses refractiveindex.info's page names).
const YAML_OF_DB_PATH: [(&str, &str); 39] = [
    ("main/Al/Rakic", "main/Al/nk/Rakic.yml"),
    ("main/Cu/Johnson", "main/Cu/nk/Johnson.yml"),
    ("main/Au/Johnson", "main/Au/nk/Johnson.yml"),
    ("main/Ag/Johnson", "main/Ag/nk/Johnson.yml"),
    ("main/Fe/Johnson", "main/Fe/nk/Johnson.yml"),
    ("main/Ni/Johnson", "main/Ni/nk/Johnson.yml"),
    ("main/Cr/Johnson", "main/Cr/nk/Johnson.yml"),
    ("main/Ti/Johnson", "main/Ti/nk/Johnson.yml"),
    ("main/W/Weaver", "main/W/nk/Weaver.yml"),
    ("main/Zn/Werner", "main/Zn/nk/Werner.yml"),
    (
        "main/Pb/Golovashkin-293K",
        "main/Pb/nk/Golovashkin-293K.yml",
    ),
    ("main/Mg/Hagemann", "main/Mg/nk/Hagemann.yml"),
    ("main/Pt/Rakic-BB", "main/Pt/nk/Rakic-BB.yml"),
    (
        "other/Cu-Zn/Querry-Cu70Zn30",
        "other/alloys/Cu-Zn/nk/Querry-Cu70Zn30.yml",
    ),
    (
        "other/stainless_steel/Karlsson-austenitic",
        "other/alloys/stainless steel/nk/Karlsson-austenitic.yml",
    ),
    ("main/Si/Aspnes", "main/Si/nk/Aspnes.yml"),
    ("main/Ge/Aspnes", "main/Ge/nk/Aspnes.yml"),
    ("main/GaAs/Aspnes", "main/GaAs/nk/Aspnes.yml"),
    ("main/C/Djurisic-o", "main/C/nk/Djurisic-o.yml"),
    (
        "other/acetylene_soot/Dlazell",
        "other/soots/acetylene soot/nk/Dalzell.yml",
    ),
    ("main/Fe2O3/Querry-o", "main/Fe2O3/nk/Querry-o.yml"),
    ("main/Fe3O4/Querry", "main/Fe3O4/nk/Querry.yml"),
    (
        "specs/SCHOTT-optical/N-BK7",
        "specs/schott/optical/N-BK7.yml",
    ),
    ("main/SiO2/Malitson", "main/SiO2/nk/Malitson.yml"),
    (
        "glass/soda-lime/Rubin-clear",
        "glass/misc/soda-lime/nk/Rubin-clear.yml",
    ),
    ("main/Al2O3/Malitson-o", "main/Al2O3/nk/Malitson-o.yml"),
    ("main/H2O/Hale", "main/H2O/nk/Hale.yml"),
    ("main/H2O/Warren-2008", "main/H2O/nk/Warren-2008.yml"),
    (
        "organic/poly_methyl_methacrylate/Sultanova",
        "organic/(C5H8O2)n - poly(methyl methacrylate)/nk/Sultanova.yml",
    ),
    (
        "organic/polycarbonate/Sultanova",
        "organic/(C16H14O3)n - polycarbonate/nk/Sultanova.yml",
    ),
    (
        "organic/polystyrene/Sultanova",
        "organic/(C8H8)n - polystyrene/nk/Sultanova.yml",
    ),
    (
        "organic/polyethylene_terephthalate/Zhang",
        "organic/(C10H8O4)n - polyethylene terephthalate/nk/Zhang.yml",
    ),
    (
        "organic/polyvinil_chloride/Zhang",
        "organic/(C2H3Cl)n - polyvinyl chloride/nk/Zhang.yml",
    ),
    (
        "organic/polydimethylsiloxane/Schneider-Sylgard184",
        "organic/(C2H6OSi)n - polydimethylsiloxane/nk/Schneider-Sylgard184.yml",
    ),
    (
        "organic/cellulose/Sultanova",
        "organic/(C6H10O5)n - cellulose/nk/Sultanova.yml",
    ),
    (
        "other/Kapton/French",
        "other/commercial polymers/Kapton/nk/French.yml",
    ),
    ("main/TiO2/Devore-o", "main/TiO2/nk/Devore-o.yml"),
    ("main/ZnO/Bond-o", "main/ZnO/nk/Bond-o.yml"),
    ("main/CaCO3/Ghosh-o", "main/CaCO3/nk/Ghosh-o.yml"),
];

/// Half of one unit in the last digit the built-in CSV prints: `n_band` has 5 decimals,
/// `k_band` 5 significant digits.
fn half_unit(v: f64, is_k: bool) -> f64 {
    if !is_k {
        return 0.5e-5;
    }
    if v == 0.0 {
        return 0.0;
    }
    0.5 * 10f64.powf(v.abs().log10().floor() - 4.0)
}

/// A `--names` map for the built-in library: the built-in CSV's names and categories for
/// the YAML files it was built from.
fn builtin_names_map(dir: &Path) -> PathBuf {
    let t = CsvTable::read(&data().join("materials").join("library_650nm.csv")).unwrap();
    let (c_name, c_cat, c_db) = (
        t.require("name").unwrap(),
        t.require("category").unwrap(),
        t.require("db_path").unwrap(),
    );
    let mut map = String::from("file,name,category\n");
    for r in 0..t.rows.len() {
        let db_path = t.text(r, c_db);
        let file = YAML_OF_DB_PATH
            .iter()
            .find(|(d, _)| *d == db_path)
            .unwrap_or_else(|| panic!("no YAML for {db_path}"))
            .1;
        map.push_str(&format!(
            "\"{file}\",{},{}\n",
            t.text(r, c_name),
            t.text(r, c_cat)
        ));
    }
    let p = dir.join("names.csv");
    fs::write(&p, map).unwrap();
    p
}

#[test]
fn library_at_650nm_reproduces_the_builtin_library() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let map = builtin_names_map(d);
    let o = polarid_in(
        d,
        &[
            "library",
            db().to_str().unwrap(),
            "--band",
            "610:690",
            "--names",
            map.to_str().unwrap(),
            "-o",
            "lib650.csv",
        ],
    );
    ok(&o);
    let ours = Library::read_csv(&d.join("lib650.csv")).unwrap();
    let builtin = Library::builtin().unwrap();
    assert_eq!(ours.materials.len(), 39);
    assert_eq!(builtin.materials.len(), 39);
    let mut failures = Vec::new();
    for b in &builtin.materials {
        let m = material(&ours, &b.name);
        assert_eq!(m.category, b.category, "{}", b.name);
        for (label, ours, printed, is_k) in [("n", m.n, b.n, false), ("k", m.k, b.k, true)] {
            let tol = half_unit(printed, is_k) + 1e-12 * printed.abs();
            if (ours - printed).abs() > tol {
                failures.push(format!(
                    "{} {label}: library {ours:e}, built-in {printed:e} (tol {tol:.1e})",
                    b.name
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The comment line records the band; the reference is the YAML path by default.
    let csv = fs::read_to_string(d.join("lib650.csv")).unwrap();
    assert!(csv.starts_with("# polarid library:"), "{csv}");
    assert!(
        csv.contains("610–690 nm: mean of 81 samples every 1 nm"),
        "{csv}"
    );
    assert_eq!(
        material(&ours, "gold").reference.as_deref(),
        Some("main/Au/nk/Johnson.yml")
    );
}

#[test]
fn library_at_532nm_differs_where_it_should() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let db = db();
    let db = db.to_str().unwrap();
    // Default names (BOOK_PAGE), to standard output.
    let o = polarid_in(d, &["library", db, "--band", "532", "--category", "x"]);
    ok(&o);
    let lib532 = Library::from_csv_text("stdout", &text(&o.stdout)).unwrap();
    assert_eq!(lib532.materials.len(), 39);
    // Johnson and Christy 1972 nodes around 532 nm, linearly interpolated by hand.
    let t = (0.532 - 0.5209) / (0.5486 - 0.5209);
    let au = material(&lib532, "Au_Johnson");
    let (n, k) = (0.62 + (0.43 - 0.62) * t, 2.081 + (2.455 - 2.081) * t);
    assert!(
        (au.n - n).abs() < 1e-12 && (au.k - k).abs() < 1e-12,
        "{au:?}"
    );
    let cu = material(&lib532, "Cu_Johnson");
    let (n, k) = (1.18 + (1.02 - 1.18) * t, 2.608 + (2.577 - 2.608) * t);
    assert!(
        (cu.n - n).abs() < 1e-12 && (cu.k - k).abs() < 1e-12,
        "{cu:?}"
    );
    assert_eq!(au.category.as_deref(), Some("x"));
    // Fused silica, Malitson's Sellmeier formula at 0.532 µm.
    let c = [
        0.6961663, 0.0684043, 0.4079426, 0.1162414, 0.8974794, 9.896161,
    ];
    let l2 = 0.532f64 * 0.532;
    let n2 = 1.0
        + (0..3)
            .map(|i| c[2 * i] * l2 / (l2 - c[2 * i + 1] * c[2 * i + 1]))
            .sum::<f64>();
    let si = material(&lib532, "SiO2_Malitson");
    assert!((si.n - n2.sqrt()).abs() < 1e-12 && si.k == 0.0, "{si:?}");
    assert!((si.n - 1.46071).abs() < 5e-5, "{si:?}");

    // The 520-545 nm band: gold and copper are far from their 650 nm values (interband
    // absorption), fused silica is not.
    let o = polarid_in(d, &["library", db, "--band", "520:545", "-o", "lib532.csv"]);
    ok(&o);
    let band = Library::read_csv(&d.join("lib532.csv")).unwrap();
    let builtin = Library::builtin().unwrap();
    for (name, old) in [("Au_Johnson", "gold"), ("Cu_Johnson", "copper")] {
        let (m, b) = (material(&band, name), material(&builtin, old));
        assert!(
            m.n > b.n + 0.3 && m.k < b.k - 0.9,
            "{name}: {m:?} vs 650 nm {b:?}"
        );
    }
    let (m, b) = (
        material(&band, "SiO2_Malitson"),
        material(&builtin, "fused_silica"),
    );
    assert!(
        m.n > b.n && m.n - b.n < 0.01,
        "fused silica: {m:?} vs {b:?}"
    );
    // Gold's band mean lies between its values at the band's ends.
    let ends: Vec<f64> = ["520", "545"]
        .iter()
        .map(|wl| {
            let o = polarid_in(d, &["library", db, "--band", wl]);
            ok(&o);
            material(
                &Library::from_csv_text("stdout", &text(&o.stdout)).unwrap(),
                "Au_Johnson",
            )
            .n
        })
        .collect();
    let au = material(&band, "Au_Johnson").n;
    assert!(au < ends[0] && au > ends[1], "{au} not in {ends:?}");
}

#[test]
fn library_output_feeds_classify() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let m = db();
    let f = |p: &str| m.join(p).display().to_string();
    let metals = d.join("metal");
    fs::create_dir(&metals).unwrap();
    for (src, dst) in [
        ("main/Au/nk/Johnson.yml", "gold.yml"),
        ("main/Cu/nk/Johnson.yml", "copper.yml"),
        ("main/Al/nk/Rakic.yml", "aluminum.yaml"),
    ] {
        fs::copy(m.join(src), metals.join(dst)).unwrap();
    }
    // A folder `metal/` gives the category; files given directly take --category.
    let o = polarid_in(
        d,
        &[
            "library",
            "metal",
            &f("main/SiO2/nk/Malitson.yml"),
            &f("main/Si/nk/Aspnes.yml"),
            "--band",
            "520:545",
            "--category",
            "dielectric",
            "-o",
            "lib.csv",
        ],
    );
    ok(&o);
    let lib = Library::read_csv(&d.join("lib.csv")).unwrap();
    let names: Vec<&str> = lib.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(
        names,
        ["aluminum", "copper", "gold", "SiO2_Malitson", "Si_Aspnes"]
    );
    assert_eq!(material(&lib, "gold").category.as_deref(), Some("metal"));
    assert_eq!(
        material(&lib, "SiO2_Malitson").category.as_deref(),
        Some("dielectric")
    );
    // Fits near each library value (offsets well inside half the gaps between materials).
    let mut fits =
        String::from("target,class,n,k,n_se,k_se,nk_corr,rms_residual,measurements,status\n");
    for (i, mat) in lib.materials.iter().enumerate() {
        let dn = if i % 2 == 0 { 0.03 } else { -0.02 };
        fits.push_str(&format!(
            "T{i},{},{},{},0.05,0.05,0,0.001,9,ok\n",
            mat.name,
            mat.n + dn,
            mat.k - dn
        ));
    }
    fs::write(d.join("fits.csv"), fits).unwrap();
    let o = polarid_in(
        d,
        &[
            "classify",
            "fits.csv",
            "--library",
            "lib.csv",
            "-o",
            "out.csv",
        ],
    );
    ok(&o);
    let t = CsvTable::read(&d.join("out.csv")).unwrap();
    let (c_class, c_pred, c_cat) = (
        t.require("class").unwrap(),
        t.require("predicted").unwrap(),
        t.require("category").unwrap(),
    );
    assert_eq!(t.rows.len(), 5);
    for r in 0..t.rows.len() {
        assert_eq!(t.text(r, c_pred), t.text(r, c_class), "row {r}");
    }
    assert_eq!(t.text(2, c_cat), "metal");
    // The 532 nm gold estimate is not gold against the built-in 650 nm library: the
    // band matters.
    fs::write(
        d.join("gold532.csv"),
        format!(
            "target,n,k\nG,{},{}\n",
            material(&lib, "gold").n,
            material(&lib, "gold").k
        ),
    )
    .unwrap();
    let o = polarid_in(d, &["classify", "gold532.csv", "--library", "builtin"]);
    ok(&o);
    let t = CsvTable::from_reader(Path::new("stdout"), &o.stdout[..]).unwrap();
    let pred = t.text(0, t.require("predicted").unwrap()).to_string();
    assert_ne!(pred, "gold");
}

#[test]
fn skip_missing_skips_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let db = db();
    // GaAs (Aspnes) stops at 826.6 nm: an error for a 700-900 nm band ...
    let o = polarid_in(
        d,
        &[
            "library",
            db.to_str().unwrap(),
            "--band",
            "700:900",
            "-o",
            "nir.csv",
        ],
    );
    bad(
        &o,
        &[
            "GaAs/nk/Aspnes.yml",
            "700–900 nm",
            "826.6 nm",
            "--skip-missing",
        ],
    );
    assert!(listing(d).is_empty(), "{:?}", listing(d));
    // ... skipped, with a warning naming it, under --skip-missing.
    let o = polarid_in(
        d,
        &[
            "library",
            db.to_str().unwrap(),
            "--band",
            "700:900",
            "--skip-missing",
            "-o",
            "nir.csv",
        ],
    );
    ok(&o);
    let e = text(&o.stderr);
    assert!(
        e.contains("warning") && e.contains("GaAs/nk/Aspnes.yml"),
        "{e}"
    );
    let lib = Library::read_csv(&d.join("nir.csv")).unwrap();
    assert!(lib.materials.iter().all(|m| m.name != "GaAs_Aspnes"));
    assert!(lib.materials.len() < 39 && lib.materials.len() > 20);
    assert!(material(&lib, "Au_Johnson").k > 4.0);
}

#[test]
fn bad_inputs_exit_2_name_file_field_value_and_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let w = |name: &str, s: &str| {
        let p = d.join(name);
        fs::create_dir_all(p.parent().unwrap()).unwrap();
        fs::write(&p, s).unwrap();
    };
    w(
        "in/nir.yml",
        "DATA:\n  - type: tabulated nk\n    data: |\n        0.70 1.0 2.0\n        0.90 2.0 4.0\n",
    );
    w(
        "in/good.yml",
        "DATA:\n  - type: tabulated nk\n    data: |\n        0.40 1.0 2.0\n        0.90 2.0 4.0\n",
    );
    w(
        "bad/number.yml",
        "DATA:\n  - type: tabulated nk\n    data: |\n        0.40 1.0 2.0\n        0.90 x2 4.0\n",
    );
    w("bad/notyaml.yml", "DATA: [unclosed\n");
    w(
        "bad/formula.yml",
        "DATA:\n  - type: formula 12\n    coefficients: 1\n",
    );
    w(
        "a/Au/nk/J.yml",
        &fs::read_to_string(d.join("in/good.yml")).unwrap(),
    );
    w(
        "b/Au/nk/J.yml",
        &fs::read_to_string(d.join("in/good.yml")).unwrap(),
    );
    w("empty/readme.txt", "no yaml here");
    w(
        "unknown.yml",
        &fs::read_to_string(d.join("in/good.yml")).unwrap(),
    );
    w("map_none.csv", "file,name\nnope/J.yml,foo\n");
    w("map_many.csv", "file,name\nnk/J.yml,foo\n");
    w("map_badname.csv", "file,name\na/Au/nk/J.yml,unknown\n");
    let before = listing(d);
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        // Band outside a file's data: file, band, the data's range.
        (
            vec!["in", "--band", "520:545"],
            vec!["nir.yml", "band 520–545 nm", "700.0–900.0 nm"],
        ),
        (
            vec!["in/nir.yml", "--band", "532"],
            vec!["nir.yml", "532 nm", "700.0–900.0 nm"],
        ),
        // Bad band syntax, empty band, bad step.
        (vec!["in", "--band", "5x0:545"], vec!["--band", "5x0"]),
        (
            vec!["in", "--band", "545:520"],
            vec!["--band", "empty band", "545"],
        ),
        (vec!["in", "--band", "0"], vec!["--band", "\"0\""]),
        (
            vec!["in", "--band", "600", "--step=-1"],
            vec!["--step", "\"-1\""],
        ),
        (
            vec!["in/good.yml", "--band", "500:800", "--step", "1e-9"],
            vec!["--step", "samples"],
        ),
        // Unreadable YAML: the file, the field, the value.
        (
            vec!["bad/number.yml", "--band", "500"],
            vec!["number.yml", "data", "\"x2\""],
        ),
        (
            vec!["bad/notyaml.yml", "--band", "500"],
            vec!["notyaml.yml", "YAML"],
        ),
        (
            vec!["bad/formula.yml", "--band", "500"],
            vec!["formula.yml", "formula 12"],
        ),
        (vec!["missing.yml", "--band", "500"], vec!["missing.yml"]),
        (vec!["empty", "--band", "500"], vec!["empty", "*.yml"]),
        // Names: two default names alike, a reserved name, bad maps.
        (
            vec!["a", "b", "--band", "500"],
            vec!["Au_J", "a/Au/nk/J.yml", "b/Au/nk/J.yml", "--names"],
        ),
        (
            vec!["unknown.yml", "--band", "500"],
            vec!["unknown.yml", "reserved"],
        ),
        (
            vec!["a", "b", "--band", "500", "--names", "map_none.csv"],
            vec![
                "map_none.csv",
                "line 2",
                "`file`",
                "nope/J.yml",
                "matches none",
            ],
        ),
        (
            vec!["a", "b", "--band", "500", "--names", "map_many.csv"],
            vec!["map_many.csv", "line 2", "nk/J.yml", "matches 2"],
        ),
        (
            vec!["a", "--band", "500", "--names", "map_badname.csv"],
            vec!["map_badname.csv", "line 2", "`name`", "reserved"],
        ),
        // Everything skipped.
        (
            vec!["in/nir.yml", "--band", "532", "--skip-missing"],
            vec!["532 nm", "skipped"],
        ),
    ];
    for (args, words) in cases {
        let mut all = vec!["library"];
        all.extend(&args);
        all.extend(["-o", "out.csv"]);
        let o = polarid_in(d, &all);
        bad(&o, &words);
        assert_eq!(listing(d), before, "{args:?} left output behind");
    }
    // An existing output is kept unless --force.
    w("out.csv", "keep\n");
    let o = polarid_in(
        d,
        &["library", "in/good.yml", "--band", "500", "-o", "out.csv"],
    );
    bad(&o, &["out.csv", "--force"]);
    assert_eq!(fs::read_to_string(d.join("out.csv")).unwrap(), "keep\n");
    let o = polarid_in(
        d,
        &[
            "--force",
            "library",
            "in/good.yml",
            "--band",
            "500",
            "-o",
            "out.csv",
        ],
    );
    ok(&o);
    let lib = Library::read_csv(&d.join("out.csv")).unwrap();
    assert_eq!(lib.materials.len(), 1);
    assert_eq!(lib.materials[0].name, "good");
    assert!((lib.materials[0].n - 1.2).abs() < 1e-12, "{lib:?}");
}
