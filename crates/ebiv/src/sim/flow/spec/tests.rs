//! Tests of `FlowSpec`: the TOML form, validation and building.

use super::*;
use crate::sim::flow::{Flow, LambOseenVortex};

#[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
struct Scenario {
    flow: FlowSpec,
}

#[test]
fn flow_spec_reads_the_documented_toml() {
    let text = r#"
        [flow]
        type = "lamb_oseen"
        centre = [160.0, 120.0]
        circulation = 2500.0
        core_radius = 40.0
    "#;
    let scenario: Scenario = toml::from_str(text).unwrap();
    assert_eq!(
        scenario.flow,
        FlowSpec::LambOseen {
            centre: [160.0, 120.0],
            circulation: 2500.0,
            core_radius: 40.0
        }
    );
    let flow = scenario.flow.build().unwrap();
    let direct = LambOseenVortex {
        centre: (160.0, 120.0),
        circulation_px2_per_ms: 2500.0,
        core_radius_px: 40.0,
    };
    assert_eq!(
        flow.velocity(200.0, 133.0, 0.0),
        direct.velocity(200.0, 133.0, 0.0)
    );
    assert_eq!(
        flow.advect((200.0, 133.0), 0.0, 9e3),
        direct.advect((200.0, 133.0), 0.0, 9e3)
    );
}

fn every_spec() -> Vec<FlowSpec> {
    vec![
        FlowSpec::Uniform {
            u: Some(1.5),
            v: Some(2.598),
            speed: None,
            angle_deg: None,
        },
        FlowSpec::Uniform {
            u: None,
            v: None,
            speed: Some(2.5),
            angle_deg: Some(30.0),
        },
        FlowSpec::SolidBody {
            centre: [128.0, 128.0],
            omega: 0.06,
        },
        FlowSpec::Rankine {
            centre: [160.0, 120.0],
            omega: 0.1,
            core_radius: 100.0,
        },
        FlowSpec::LambOseen {
            centre: [128.0, 128.0],
            circulation: 5000.0,
            core_radius: 40.0,
        },
        FlowSpec::Couette {
            gradient: 0.05,
            y0: 120.0,
            x0: 160.0,
            angle_deg: 22.3,
        },
        FlowSpec::MixingLayer {
            u1: 0.05,
            u2: 5.0,
            y0: 64.0,
            thickness: 8.0,
            x0: 0.0,
            angle_deg: 0.0,
        },
        FlowSpec::MixingLayer {
            u1: -2.0,
            u2: 3.0,
            y0: 100.0,
            thickness: 4.0,
            x0: 50.0,
            angle_deg: 45.0,
        },
        FlowSpec::Poiseuille {
            u_max: 10.0,
            y_min: 0.0,
            y_max: 240.0,
        },
        FlowSpec::Sinusoidal {
            amplitude: 6.0,
            wavelength: 128.0,
            speed: 5.0,
        },
        FlowSpec::Cellular {
            amplitude: 10.0,
            period: 128.0,
        },
        FlowSpec::Stagnation {
            centre: [160.0, 240.0],
            k: 0.02,
        },
        FlowSpec::Superposition {
            flows: vec![
                FlowSpec::Rankine {
                    centre: [160.0, 120.0],
                    omega: 0.1,
                    core_radius: 50.0,
                },
                FlowSpec::Uniform {
                    u: Some(2.0),
                    v: Some(0.0),
                    speed: None,
                    angle_deg: None,
                },
            ],
        },
        FlowSpec::Gridded {
            path: "fields/dns.nc".into(),
        },
    ]
}

#[test]
fn flow_spec_round_trips_through_toml() {
    for spec in every_spec() {
        let scenario = Scenario { flow: spec };
        let text = toml::to_string(&scenario).unwrap();
        let back: Scenario = toml::from_str(&text).unwrap();
        assert_eq!(back, scenario, "through\n{text}");
        if !matches!(scenario.flow, FlowSpec::Gridded { .. }) {
            scenario.flow.build().unwrap();
        }
    }
}

#[test]
fn flow_spec_optional_keys_and_names() {
    let s: Scenario =
        toml::from_str("[flow]\ntype = \"couette\"\ngradient = 0.1\ny0 = 5.0").unwrap();
    assert_eq!(
        s.flow,
        FlowSpec::Couette {
            gradient: 0.1,
            y0: 5.0,
            x0: 0.0,
            angle_deg: 0.0
        }
    );
    let text = "[flow]\ntype = \"mixing_layer\"\nu1 = 0.05\nu2 = 5.0\ny0 = 64.0\nthickness = 8.0";
    let s: Scenario = toml::from_str(text).unwrap();
    assert_eq!(
        s.flow,
        FlowSpec::MixingLayer {
            u1: 0.05,
            u2: 5.0,
            y0: 64.0,
            thickness: 8.0,
            x0: 0.0,
            angle_deg: 0.0
        }
    );
    let (u, v) = s.flow.build().unwrap().velocity(0.0, 64.0, 0.0);
    assert!((u - 2.525).abs() < 1e-12 && v == 0.0, "({u}, {v})");
    assert_eq!(
        FlowSpec::uniform(1.5, -2.0)
            .build()
            .unwrap()
            .velocity(0.0, 0.0, 0.0),
        (1.5, -2.0)
    );
    let s: Scenario = toml::from_str("[flow]\ntype = \"uniform\"\nspeed = 2.0").unwrap();
    let (u, v) = s.flow.build().unwrap().velocity(0.0, 0.0, 0.0);
    assert_eq!((u, v), (2.0, 0.0));
    let text = "[flow]\ntype = \"superposition\"\n\
                [[flow.flows]]\ntype = \"solid_body\"\ncentre = [1.0, 2.0]\nomega = 0.1\n\
                [[flow.flows]]\ntype = \"stagnation\"\ncentre = [0.0, 0.0]\nk = 0.01\n";
    let s: Scenario = toml::from_str(text).unwrap();
    assert!(matches!(s.flow, FlowSpec::Superposition { ref flows } if flows.len() == 2));
    // Misspelt keys and unknown types are rejected, not ignored.
    let typo = "[flow]\ntype = \"rankine\"\ncentre = [0.0, 0.0]\nomega = 1.0\ncore_radious = 3.0";
    assert!(toml::from_str::<Scenario>(typo).is_err());
    assert!(toml::from_str::<Scenario>("[flow]\ntype = \"hurricane\"").is_err());
}

fn parameter_name(spec: FlowSpec) -> String {
    match spec.build() {
        Err(Error::Parameter { name, .. }) => name,
        other => panic!("{spec:?}: expected a parameter error, got {other:?}"),
    }
}

#[test]
fn flow_spec_rejects_bad_parameters_by_name() {
    let lamb = |core_radius| FlowSpec::LambOseen {
        centre: [0.0, 0.0],
        circulation: 100.0,
        core_radius,
    };
    assert_eq!(parameter_name(lamb(0.0)), "core_radius");
    assert_eq!(parameter_name(lamb(-3.0)), "core_radius");
    assert_eq!(parameter_name(lamb(f64::NAN)), "core_radius");
    let bad_centre = FlowSpec::SolidBody {
        centre: [f64::INFINITY, 0.0],
        omega: 0.1,
    };
    assert_eq!(parameter_name(bad_centre), "centre");
    let channel = FlowSpec::Poiseuille {
        u_max: 1.0,
        y_min: 50.0,
        y_max: 50.0,
    };
    assert_eq!(parameter_name(channel), "y_max");
    let waves = FlowSpec::Sinusoidal {
        amplitude: 5.0,
        wavelength: 0.0,
        speed: 1.0,
    };
    assert_eq!(parameter_name(waves), "wavelength");
    let cells = FlowSpec::Cellular {
        amplitude: f64::NAN,
        period: 128.0,
    };
    assert_eq!(parameter_name(cells), "amplitude");
    let half = FlowSpec::Uniform {
        u: Some(1.0),
        v: None,
        speed: None,
        angle_deg: None,
    };
    assert_eq!(parameter_name(half), "v");
    let both = FlowSpec::Uniform {
        u: Some(1.0),
        v: Some(1.0),
        speed: Some(1.0),
        angle_deg: None,
    };
    assert_eq!(parameter_name(both), "speed");
    let layer = |thickness| FlowSpec::MixingLayer {
        u1: 0.0,
        u2: 1.0,
        y0: 0.0,
        thickness,
        x0: 0.0,
        angle_deg: 0.0,
    };
    assert_eq!(parameter_name(layer(0.0)), "thickness");
    assert_eq!(parameter_name(layer(-1.0)), "thickness");
    assert_eq!(parameter_name(layer(f64::INFINITY)), "thickness");
    let nested = FlowSpec::Superposition {
        flows: vec![
            FlowSpec::Stagnation {
                centre: [0.0, 0.0],
                k: 0.1,
            },
            lamb(0.0),
        ],
    };
    assert_eq!(parameter_name(nested), "flows[1].core_radius");
    assert_eq!(
        parameter_name(FlowSpec::Superposition { flows: vec![] }),
        "flows"
    );
}

#[test]
fn gridded_spec_names_the_missing_file_and_resolves_relative_paths() {
    let spec = FlowSpec::Gridded {
        path: "no/such/field.csv".into(),
    };
    let message = spec.build().unwrap_err().to_string();
    assert!(message.contains("no/such/field.csv"), "{message}");
    let nested = FlowSpec::Superposition {
        flows: vec![
            spec.clone(),
            FlowSpec::Gridded {
                path: "/abs.nc".into(),
            },
        ],
    };
    let resolved = nested.with_base_dir(std::path::Path::new("/data/run"));
    let FlowSpec::Superposition { flows } = resolved else {
        panic!("not a superposition")
    };
    assert_eq!(
        flows,
        vec![
            FlowSpec::Gridded {
                path: "/data/run/no/such/field.csv".into()
            },
            FlowSpec::Gridded {
                path: "/abs.nc".into()
            }
        ]
    );
}

#[test]
fn random_vortices_are_read_from_toml_and_checked() {
    let text = "type = \"random_vortices\"\ncount = 8\ncore_radius = 16.0\nspeed = 1.5\n\
                region = [128.0, 96.0]\nmean = [1.0, 0.0]\n";
    let spec: FlowSpec = toml::from_str(text).unwrap();
    let flow = spec.build().unwrap();
    assert!(flow.max_speed(128.0, 96.0, 0.0) > 1.0);
    let far = flow.velocity(1e7, 1e7, 0.0);
    assert!((far.0 - 1.0).abs() < 1e-4 && far.1.abs() < 1e-4, "{far:?}");
    let vortices = |count, region| FlowSpec::RandomVortices {
        count,
        core_radius: 16.0,
        speed: 1.5,
        region,
        mean: [0.0, 0.0],
        seed: 1,
    };
    assert_eq!(parameter_name(vortices(0, [128.0, 96.0])), "count");
    let flat = vortices(3, [128.0, 0.0]);
    assert_eq!(parameter_name(flat), "region");
}
