//! Tests of `params.rs`.

use super::*;

#[derive(Clone, Debug, PartialEq)]
struct P {
    sigma_px: f64,
    n: i64,
    mode: &'static str,
    pts: Vec<[f64; 2]>,
}
impl Default for P {
    fn default() -> Self {
        Self {
            sigma_px: 2.0,
            n: 3,
            mode: "a",
            pts: vec![],
        }
    }
}
impl Params for P {
    fn visit(&mut self, v: &mut dyn ParamVisitor) {
        v.float(
            "sigma_px",
            &mut self.sigma_px,
            &Meta::new("σ").range(0.1, 10.0),
        );
        v.int("n", &mut self.n, &Meta::new("n").range(1.0, 5.0));
        v.choice("mode", &mut self.mode, &["a", "bee"], &Meta::new("m"));
        v.points("pts", &mut self.pts, &Meta::new("p"));
    }
}

#[test]
fn round_trip_and_errors() {
    let p = P {
        sigma_px: 4.5,
        mode: "bee",
        pts: vec![[1.0, 2.0]],
        ..P::default()
    };
    let v = to_values(&p);
    assert_eq!(v.len(), 4);
    assert_eq!(from_values::<P>(&v), Ok(p));
    let mut bad = BTreeMap::new();
    bad.insert("sigma".to_string(), ParamValue::Float(1.0));
    match from_values::<P>(&bad) {
        Err(ParamError::Unknown { suggestion, .. }) => {
            assert_eq!(suggestion.as_deref(), Some("sigma_px"))
        }
        other => panic!("{other:?}"),
    }
    bad.clear();
    bad.insert("n".into(), ParamValue::Int(9));
    assert!(matches!(
        from_values::<P>(&bad),
        Err(ParamError::Range { .. })
    ));
    bad.insert("n".into(), ParamValue::Bool(true));
    assert!(matches!(
        from_values::<P>(&bad),
        Err(ParamError::Kind { .. })
    ));
    bad.clear();
    bad.insert("mode".into(), ParamValue::Choice("be".into()));
    let e = from_values::<P>(&bad).unwrap_err().to_string();
    assert!(e.contains("did you mean \"bee\""), "{e}");
}

#[test]
fn parse_strings_by_kind() {
    let info = describe::<P>();
    assert_eq!(info[0].parse_str("2.5"), Ok(ParamValue::Float(2.5)));
    assert!(info[1].parse_str("2.5").is_err());
    assert_eq!(
        info[3].parse_str("1:2,3:4"),
        Ok(ParamValue::Points(vec![[1.0, 2.0], [3.0, 4.0]]))
    );
    assert_eq!(edit_distance("kitten", "sitting"), 3);
    assert_eq!(
        nearest("gausian", ["gaussian", "box"]).as_deref(),
        Some("gaussian")
    );
    assert_eq!(nearest("zzzzzz", ["gaussian", "box"]), None);
}
