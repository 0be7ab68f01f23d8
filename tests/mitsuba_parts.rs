//! The parts of the Mitsuba importer (`lumis::import`): relative paths, the files' versions and
//! parameters, property names and spectra.

/// The tests of `lumis::import::mitsuba::paths` (`src/import/mitsuba/paths.rs`).
mod paths {
    use lumis::import::mitsuba::paths::*;
    use std::path::{Path, PathBuf};

    #[test]
    fn relative_paths_climb_to_the_common_directory() {
        assert_eq!(
            relative_path(Path::new("/a/b/meshes/x.obj"), Path::new("/a/c")),
            PathBuf::from("../b/meshes/x.obj")
        );
        // An output given as a bare file name: its folder is the empty path.
        let here = std::env::current_dir().unwrap();
        assert_eq!(
            relative_path(&here.join("./meshes/x.obj"), Path::new("")),
            PathBuf::from("meshes/x.obj")
        );
        assert_eq!(
            relative_path(Path::new("/a/./b/../x.obj"), Path::new("/a")),
            PathBuf::from("x.obj")
        );
    }
}

/// The tests of `lumis::import::mitsuba::files` (`src/import/mitsuba/files.rs`).
mod files {

    use std::collections::BTreeMap;

    use lumis::import::mitsuba::files::*;

    #[test]
    fn versions_parse_and_order() {
        assert_eq!(Version::parse("0.5.0"), Some(Version(0, 5, 0)));
        assert_eq!(Version::parse("3.0"), Some(Version(3, 0, 0)));
        assert_eq!(Version::parse("x"), None);
        assert!(Version(0, 6, 0).is_legacy() && !Version(2, 0, 0).is_legacy());
    }

    #[test]
    fn parameters_substitute_longest_first() {
        let p = BTreeMap::from([
            ("spp".to_string(), "4".to_string()),
            ("spp2".to_string(), "8".to_string()),
        ]);
        assert_eq!(substitute("$spp2 $spp", &p).unwrap(), "8 4");
        assert!(substitute("$nope", &p).unwrap_err().contains("$nope"));
    }

    /// `\$` is a literal `$` and only a backslash before a `$` is an escape, as Mitsuba 3.9.1
    /// reads them (its outputs for these four values, with `a` defined as `ONE`).
    #[test]
    fn a_backslash_escapes_a_dollar_as_in_mitsuba() {
        let p = BTreeMap::from([("a".to_string(), "ONE".to_string())]);
        assert_eq!(substitute(r"x\$a.obj", &p).unwrap(), "x$a.obj");
        assert_eq!(substitute(r"x\\$a.obj", &p).unwrap(), r"x\$a.obj");
        assert_eq!(substitute(r"x$a\$a", &p).unwrap(), "xONE$a");
        assert!(substitute(r"\$a $b", &p).unwrap_err().contains("$b"));
    }
}

/// The tests of `lumis::import::mitsuba::properties` (`src/import/mitsuba/properties.rs`).
mod properties {
    use lumis::import::mitsuba::files::Version;

    use lumis::import::mitsuba::properties::*;

    /// Mitsuba 3's `camel_to_underscore_case` on the names 0.x scenes use.
    #[test]
    fn legacy_names_become_snake_case_as_mitsuba_makes_them() {
        for (old, new) in [
            ("toWorld", "to_world"),
            ("intIOR", "int_ior"),
            ("extIOR", "ext_ior"),
            ("sampleCount", "sample_count"),
            ("fovAxis", "fov_axis"),
            ("specularReflectance", "specular_reflectance"),
            ("maxDepth", "max_depth"),
            ("alphaU", "alpha_u"),
            ("already_snake", "already_snake"),
            ("UPPER", "UPPER"),
        ] {
            assert_eq!(snake_case(old), new, "{old}");
        }
        let legacy = Version(0, 5, 0);
        assert_eq!(
            upgraded_name("diffuseReflectance", "diffuse", legacy),
            "reflectance"
        );
        assert_eq!(
            upgraded_name("diffuseReflectance", "plastic", legacy),
            "diffuse_reflectance"
        );
        assert_eq!(upgraded_name("toWorld", "obj", Version(3, 0, 0)), "toWorld");
    }
}

/// The tests of `lumis::import::mitsuba::spectrum` (`src/import/mitsuba/spectrum.rs`).
mod spectrum {

    use lumis::import::mitsuba::spectrum::*;

    /// Values Mitsuba 3.9.1's loader gives (`scalar_rgb`, printed to 6 digits: a `diffuse`
    /// reflectance through `mi.traverse`, a `constant` emitter's `eval`): reflectances bounded
    /// and under D65, emitters unbounded and without it. Mitsuba sums in f32, lumis in f64:
    /// they agree within 5·10⁻⁶.
    #[test]
    fn spectra_become_the_colours_mitsuba_gives_them() {
        let s = parse("400:0.1, 500:0.5 600:0.9, 700:0.3").unwrap();
        let close = |a: [f64; 3], b: [f64; 3]| {
            a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 5e-6 * y.abs().max(1.0))
        };
        let reflectance = to_rgb(&s, false);
        assert!(
            close(reflectance, [0.854797, 0.68754, 0.265015]),
            "{reflectance:?}"
        );
        let emission = to_rgb(&s, true);
        assert!(
            close(emission, [0.999234, 0.6597, 0.229444]),
            "{emission:?}"
        );
        let flat = parse("300:1 900:1").unwrap();
        assert!(close(to_rgb(&flat, true), [1.20488, 0.948228, 0.909267]));
        assert!(close(to_rgb(&flat, false), [0.998985, 0.998874, 0.998802]));
        // A uniform spectrum: grey on a reflectance, D65's complement on an emitter.
        assert_eq!(to_rgb(&Spectrum::Uniform(0.5), false), [0.5; 3]);
        let white = to_rgb(&Spectrum::Uniform(2.0), true);
        assert!(
            close(white, [2.0 * 1.20479, 2.0 * 0.948291, 2.0 * 0.908916]),
            "{white:?}"
        );
    }

    #[test]
    fn malformed_spectra_are_refused_with_the_reason() {
        assert!(parse("500:1").unwrap_err().contains("at least two"));
        assert!(parse("600:1, 500:2").unwrap_err().contains("must increase"));
        assert!(parse("500:1, 500:2").unwrap_err().contains("must increase"));
        assert!(
            parse("500:x, 600:1")
                .unwrap_err()
                .contains("not a finite number")
        );
        assert!(parse("1 2").unwrap_err().contains("pair"));
        assert_eq!(parse(" 0.25 ").unwrap(), Spectrum::Uniform(0.25));
    }

    /// The tables are the CIE's: ȳ peaks at 1 at 555 nm, D65 is 100 at 560 nm.
    #[test]
    fn the_tables_are_the_cie_s() {
        let at = |nm: usize| CIE[(nm - 360) / 5];
        assert_eq!(at(555)[1], 1.0);
        assert_eq!(at(560)[3], 100.0);
    }
}
