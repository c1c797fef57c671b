//! A scenario from TOML: the file's keys onto [`Scenario`], a geographic start resolved into the plane,
//! and an error that names the key and the line of what was wrong.

use super::*;

/// The scenario of a process: `path` (or the default) with `--steps` / `--seed` applied, validated —
/// the same rule as `uavloc simulate`, so every process of a run agrees on it.
pub fn load_scenario(path: Option<&Path>, steps: Option<usize>, seed: Option<u64>) -> Result<Scenario, ScenarioError> {
    let mut sc = match path {
        Some(p) => Scenario::from_file(p)?,
        None => Scenario::default(),
    };
    if let Some(n) = steps {
        sc.steps = n;
    }
    if let Some(s) = seed {
        sc.seed = s;
    }
    sc.validate()?;
    sc.check_path()?;
    sc.check_start()?;
    Ok(sc)
}

impl Scenario {
    /// Parses TOML and validates.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        let mut scenario: Scenario = toml::from_str(text).map_err(|e| parse_error(text, &e))?;
        let table: toml::Table = text.parse().map_err(|e| parse_error(text, &e))?;
        scenario.resolve_geographic(&table)?;
        scenario.validate()?;
        Ok(scenario)
    }

    /// Converts `uavs_lat_lon_deg` / `emitter_lat_lon_deg` into `uavs` / `emitter` in the origin's plane
    /// (and clears them): each position is given once, and only with an origin.
    fn resolve_geographic(&mut self, table: &toml::Table) -> Result<(), ScenarioError> {
        let geo_uavs = self.uavs_lat_lon_deg.take();
        let geo_emitter = self.emitter_lat_lon_deg.take();
        for (geo, local, given) in [
            ("uavs_lat_lon_deg", "uavs", geo_uavs.is_some()),
            ("emitter_lat_lon_deg", "emitter", geo_emitter.is_some()),
        ] {
            if given && table.contains_key(local) {
                return Err(invalid(geo, format!("give the position once: `{local}` (metres) or `{geo}`, not both")));
            }
            if given && self.origin.is_none() {
                return Err(invalid(geo, "latitude/longitude positions need an `[origin]` (lat_deg, lon_deg, alt_m)"));
            }
        }
        let Some(origin) = self.origin else { return Ok(()) };
        let frame = LocalFrame::new(origin).map_err(|e| invalid("origin", e.to_string()))?;
        let local = |key: String, p: [f64; 2]| {
            LatLon::new(p[0], p[1]).and_then(|p| frame.to_local(p)).map_err(|e| invalid(&key, e.to_string()))
        };
        if let Some(uavs) = geo_uavs {
            self.uavs = uavs
                .iter()
                .enumerate()
                .map(|(i, p)| local(format!("uavs_lat_lon_deg[{i}]"), *p))
                .collect::<Result<_, _>>()?;
        }
        if let Some(p) = geo_emitter {
            self.emitter = local("emitter_lat_lon_deg".into(), p)?;
        }
        Ok(())
    }

    /// Reads, parses and validates a TOML file.
    pub fn from_file(path: impl AsRef<Path>) -> Result<Self, ScenarioError> {
        let path = path.as_ref();
        let text =
            std::fs::read_to_string(path).map_err(|source| ScenarioError::Io { path: path.to_path_buf(), source })?;
        Self::from_toml_str(&text)
    }

    /// The scenario as TOML (angles in degrees).
    pub fn to_toml_string(&self) -> String {
        toml::to_string(self).expect("a scenario always serialises")
    }
}

/// Turns a TOML error into [`ScenarioError::Parse`], locating the key from the error's byte span.
fn parse_error(text: &str, err: &toml::de::Error) -> ScenarioError {
    let span = err.span();
    let line = span.as_ref().map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1);
    let key = span.and_then(|s| key_at(text, s.start));
    ScenarioError::Parse { key, line, message: err.message().trim().to_string() }
}

/// The dotted key whose value (or name) contains byte `pos`: the nearest `key =` at or above that line,
/// prefixed by the enclosing `[table]`.
fn key_at(text: &str, pos: usize) -> Option<String> {
    let pos = pos.min(text.len());
    let upto_line_end = text[pos..].find('\n').map_or(text.len(), |i| pos + i);
    let mut key: Option<String> = None;
    for raw in text[..upto_line_end].lines().rev() {
        let line = raw.trim();
        if let Some(table) = table_header(line) {
            return Some(match key {
                Some(k) => format!("{table}.{k}"),
                None => table.to_string(),
            });
        }
        if key.is_none()
            && let Some((lhs, _)) = line.split_once('=')
        {
            let lhs = lhs.trim().trim_matches('"');
            if !lhs.is_empty() && lhs.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-' || c == '.') {
                key = Some(lhs.to_string());
            }
        }
    }
    key
}

/// The name of a `[table]` or `[[array]]` header line (not a row of an inline array such as `[1.0, 2.0],`).
fn table_header(line: &str) -> Option<&str> {
    let line = line.split('#').next()?.trim();
    let inner = line.strip_prefix('[')?.strip_suffix(']')?;
    let inner = inner.trim_start_matches('[').trim_end_matches(']').trim();
    let is_key = |c: char| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | ' ' | '"');
    (!inner.is_empty() && inner.chars().all(is_key) && inner.chars().any(|c| c.is_ascii_alphabetic())).then_some(inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    const NOMINAL: &str = include_str!("../../../scenarios/nominal.toml");
    const GEO: &str = include_str!("../../../scenarios/geo.toml");

    #[test]
    fn nominal_file_is_the_default() {
        let s = Scenario::from_toml_str(NOMINAL).unwrap();
        assert_eq!(s, Scenario::default());
        Scenario::default().validate().unwrap();
    }

    /// `scenarios/geo.toml` is the nominal case given in latitude/longitude: its positions are the
    /// nominal ones to within 0.1 mm, it keeps its origin, and it reads back from its own TOML (in metres)
    /// as the same scenario.
    #[test]
    fn positions_in_latitude_longitude_are_the_nominal_ones_in_the_plane() {
        let s = Scenario::from_toml_str(GEO).unwrap();
        let d = Scenario::default();
        for (a, b) in s.uavs.iter().chain([&s.emitter]).zip(d.uavs.iter().chain([&d.emitter])) {
            assert!(dist(*a, *b) < 1e-4, "{a:?} vs {b:?}");
        }
        assert_eq!(s.origin.map(|o| o.lat_deg), Some(47.3977));
        assert!(s.uavs_lat_lon_deg.is_none() && s.emitter_lat_lon_deg.is_none(), "resolved into the plane");
        let text = s.to_toml_string();
        assert!(text.contains("[origin]") && !text.contains("lat_lon"), "{text}");
        assert_eq!(Scenario::from_toml_str(&text).unwrap(), s);
        // An origin alone changes nothing of the run's values but the fingerprint.
        let placed = Scenario { origin: s.origin, ..Scenario::default() };
        assert_ne!(placed.fingerprint(), d.fingerprint());
        assert_eq!(Scenario { origin: None, ..placed }, d);
    }

    #[test]
    fn bad_geographic_positions_are_named() {
        let origin = "[origin]\nlat_deg = 47.0\nlon_deg = 8.0\n";
        assert_eq!(key_of("emitter_lat_lon_deg = [47.1, 8.2]"), "emitter_lat_lon_deg", "no origin");
        assert_eq!(
            key_of(&format!("emitter = [1.0, 2.0]\nemitter_lat_lon_deg = [47.1, 8.2]\n{origin}")),
            "emitter_lat_lon_deg"
        );
        assert_eq!(
            key_of(&format!("uavs = [[0,0],[1,1],[2,0]]\nuavs_lat_lon_deg = [[47.1, 8.2]]\n{origin}")),
            "uavs_lat_lon_deg"
        );
        let e = Scenario::from_toml_str(&format!("emitter_lat_lon_deg = [95.0, 8.2]\n{origin}")).unwrap_err();
        assert_eq!(e.key(), Some("emitter_lat_lon_deg"));
        assert!(e.to_string().contains("latitude 95"), "{e}");
        let far = format!("uavs_lat_lon_deg = [[47.0, 8.0], [47.0, 8.1], [60.0, 8.0]]\n{origin}");
        let e = Scenario::from_toml_str(&far).unwrap_err();
        assert_eq!(e.key(), Some("uavs_lat_lon_deg[2]"));
        assert!(e.to_string().contains("from the origin"), "{e}");
        assert_eq!(key_of("[origin]\nlat_deg = 89.9\nlon_deg = 0.0"), "origin");
        assert_eq!(key_of("[origin]\nlat_deg = 10.0\nlon_deg = 0.0\nalt_m = nan"), "origin");
        assert_eq!(key_of("[origin]\nlat_deg = 10.0"), "origin");
        assert_eq!(key_of("[origin]\nlat_deg = 10.0\nlon_deg = 0.0\nheight = 3"), "origin.height");
        // Autopilot endpoints: one per UAV, with an origin, each an endpoint.
        let geo = |extra: &str| format!("autopilots = {extra}\n{GEO}");
        let ok =
            Scenario::from_toml_str(&geo(r#"["udpin:0.0.0.0:14550", "udpin:0.0.0.0:14551", "tcpout:10.0.0.2:5760"]"#))
                .unwrap();
        assert_eq!(ok.autopilots.len(), 3);
        assert_eq!(key_of(&geo(r#"["udpin:0.0.0.0:14550"]"#)), "autopilots");
        assert_eq!(key_of(&geo(r#"["udpin:0.0.0.0:14550", "x", "udpin:0.0.0.0:14552"]"#)), "autopilots[1]");
        assert_eq!(key_of(r#"autopilots = ["udpin:a:1", "udpin:a:2", "udpin:a:3"]"#), "autopilots", "no origin");
    }

    #[test]
    fn empty_file_is_the_default() {
        assert_eq!(Scenario::from_toml_str("").unwrap(), Scenario::default());
    }

    #[test]
    fn degrees_in_toml_radians_in_rust() {
        let s = Scenario::from_toml_str("delta_alpha_deg = 30\nheadings_deg = [0, 90, -180]").unwrap();
        assert!((s.delta_alpha - std::f64::consts::FRAC_PI_6).abs() < 1e-15);
        let h = s.headings.clone().unwrap();
        assert!((h[1] - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert_eq!(s.initial_headings(), h);
        let back = Scenario::from_toml_str(&s.to_toml_string()).unwrap();
        assert!((back.delta_alpha - s.delta_alpha).abs() < 1e-15);
    }

    #[test]
    fn sigma_scalar_or_list() {
        let s = Scenario::from_toml_str("sigma = [10.0, 20.0, 30.0]").unwrap();
        assert_eq!(s.range_sigmas(), vec![10.0, 20.0, 30.0]);
        assert_eq!(s.noise_model().unwrap().sigmas(), &[10.0, 20.0, 30.0]);
        assert_eq!(Scenario::default().range_sigmas(), vec![28.7712; 3]);
        let e = Scenario::from_toml_str("sigma = [10.0, 20.0]").unwrap_err();
        assert_eq!(e.key(), Some("sigma"));
    }

    fn key_of(text: &str) -> String {
        let e = Scenario::from_toml_str(text).unwrap_err();
        let key = e.key().unwrap_or_else(|| panic!("no key in {e}")).to_string();
        assert!(e.to_string().contains(&key), "{e}");
        key
    }

    #[test]
    fn unknown_keys_are_named() {
        assert_eq!(key_of("speed = 50\nsped = 3"), "sped");
        assert_eq!(key_of("[pso]\nparticles = 40\nparticle = 3"), "pso.particle");
        let e = Scenario::from_toml_str("sped = 3").unwrap_err();
        assert!(e.to_string().contains("unknown field"), "{e}");
    }

    #[test]
    fn wrong_types_are_named() {
        assert_eq!(key_of("speed = \"fast\""), "speed");
        assert_eq!(key_of("dt = 10\nsteps = 2.5"), "steps");
        assert_eq!(key_of("[aco]\nants = \"many\""), "aco.ants");
        assert_eq!(key_of("uavs = [\n  [0.0, 0.0],\n  [1.0, \"x\"],\n]"), "uavs");
        assert_eq!(key_of("target = \"oracle\""), "target");
        assert_eq!(key_of("sigma = \"x\""), "sigma");
        assert_eq!(key_of("[early_stop]\nwindow = -1"), "early_stop.window");
    }

    #[test]
    fn from_file_reports_missing_files() {
        let e = Scenario::from_file("/nonexistent/scenario.toml").unwrap_err();
        assert!(matches!(e, ScenarioError::Io { .. }));
    }
}
