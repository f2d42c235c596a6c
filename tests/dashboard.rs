//! `config/grafana-dashboard.json` loads (valid JSON, every panel has
//! queries) and every metric its queries name is one that a real gcud
//! exports: the dashboard is checked against a scrape of the binary, not
//! against a list kept by hand.

mod support;

use std::collections::BTreeSet;

use serde_json::Value;

/// The `gcud_...` metric names in a PromQL expression.
fn metric_names(expr: &str) -> Vec<String> {
    let mut names = Vec::new();
    let mut rest = expr;
    while let Some(at) = rest.find("gcud_") {
        let tail = &rest[at..];
        let end = tail
            .find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
            .unwrap_or(tail.len());
        names.push(tail[..end].to_owned());
        rest = &tail[end..];
    }
    names
}

fn dashboard() -> Value {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/config/grafana-dashboard.json");
    let text = std::fs::read_to_string(path).expect("config/grafana-dashboard.json");
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path} is not valid JSON: {e}"))
}

/// Every query of the dashboard: (panel title, expression).
fn queries(dashboard: &Value) -> Vec<(String, String)> {
    let panels = dashboard["panels"].as_array().expect("a panels array");
    assert!(!panels.is_empty(), "the dashboard has panels");
    let mut queries = Vec::new();
    for panel in panels {
        let title = panel["title"].as_str().expect("every panel has a title").to_owned();
        let targets = panel["targets"].as_array().filter(|t| !t.is_empty());
        for target in targets.unwrap_or_else(|| panic!("panel {title:?} has no queries")) {
            let expr = target["expr"].as_str();
            let expr = expr.unwrap_or_else(|| panic!("a query of {title:?} has no expr"));
            queries.push((title.clone(), expr.to_owned()));
        }
    }
    for variable in dashboard["templating"]["list"].as_array().into_iter().flatten() {
        if let Some(query) = variable["query"].as_str() {
            queries.push((format!("variable {}", variable["name"]), query.to_owned()));
        }
    }
    queries
}

/// The series names a scrape exports, as Prometheus stores them: every
/// sample's name, and for a family declared without samples yet the names
/// its samples take (a counter's `_total`, a histogram's `_bucket`, `_sum`
/// and `_count`, ...). A counter's family name itself is no series.
fn exported(scrape: &str) -> BTreeSet<String> {
    let mut names = BTreeSet::new();
    for line in scrape.lines() {
        if let Some(rest) = line.strip_prefix("# TYPE ") {
            let mut words = rest.split_whitespace();
            if let (Some(name), Some(kind)) = (words.next(), words.next()) {
                let suffixes: &[&str] = match kind {
                    "counter" => &["_total"],
                    "histogram" | "gaugehistogram" => &["_bucket", "_sum", "_count"],
                    "summary" => &["", "_sum", "_count"],
                    _ => &[""],
                };
                names.extend(suffixes.iter().map(|s| format!("{name}{s}")));
            }
        } else if !line.starts_with('#') && !line.is_empty() {
            let end = line.find(['{', ' ']).unwrap_or(line.len());
            names.insert(line[..end].to_owned());
        }
    }
    names
}

#[test]
fn the_dashboard_queries_only_metrics_that_gcud_exports() {
    let queries = queries(&dashboard());
    let wanted: BTreeSet<(String, String)> = queries
        .iter()
        .flat_map(|(title, expr)| metric_names(expr).into_iter().map(|n| (n, title.clone())))
        .collect();
    assert!(wanted.len() > 10, "the dashboard names gcud's metrics: {wanted:?}");

    let dir = tempfile::tempdir().expect("temp dir");
    let mut gcud = support::spawn_gcud(
        dir.path(),
        "[gcu]\ngroup = 5\n[metrics]\nlisten = \"127.0.0.1:0\"\n[[port]]\nid = 1\nsimulate = [1]\n\
         [[link]]\nname = \"clients\"\nrole = \"client\"\nlisten = \"127.0.0.1:0\"\n\
         [[gimbal]]\naddress = \"5.1.1\"\npan_limits_deg = [-170.0, 170.0]\n\
         [[tour]]\nname = \"round\"\naddress = \"5.1.1\"\n\
         steps = [{ pan_deg = 0.0, tilt_deg = 0.0, dwell_s = 5 }, { pan_deg = 10.0, tilt_deg = 0.0, dwell_s = 5 }]\n",
    );
    let log = dir.path().join("gcud.log");
    let address = |what: &str| support::addr_field(&support::wait_for_log_line(&log, what));
    let (clients, metrics) = (address("listening link=clients"), address("metrics at /metrics"));
    // Exchanges, so that the per-device families have samples too, and a
    // goto, so that the governed gimbal has a holder (the governance panels).
    for args in [&["position"][..], &["lens"], &["goto", "5", "0"]] {
        let out = support::gimbalctl(&[&["--tcp", &clients, "--to", "5.1.1"][..], args].concat());
        assert_eq!(out.code, 0, "{args:?}: {out:?}");
    }
    let scrape = support::http_get(&metrics, "/metrics");
    support::terminate(&mut gcud);
    assert!(scrape.starts_with("HTTP/1.1 200"), "{scrape}");

    let exported = exported(&scrape);
    let missing: Vec<String> = wanted
        .iter()
        .filter(|(name, _)| !exported.contains(name))
        .map(|(name, title)| format!("{name} (panel {title:?})"))
        .collect();
    assert!(
        missing.is_empty(),
        "the dashboard queries metrics gcud does not export: {missing:?}\nscrape:\n{scrape}"
    );
}

/// Imported into Grafana, the dashboard asks for one Prometheus data source
/// (`${DS_PROMETHEUS}`) that every panel uses, and every query follows the
/// `instance` variable.
#[test]
fn the_dashboard_imports_with_one_prometheus_input_and_an_instance_variable() {
    let dashboard = dashboard();
    let inputs = dashboard["__inputs"].as_array().expect("__inputs");
    assert!(
        inputs
            .iter()
            .any(|i| i["name"] == "DS_PROMETHEUS" && i["type"] == "datasource" && i["pluginId"] == "prometheus"),
        "{inputs:?}"
    );
    let variables = dashboard["templating"]["list"].as_array().expect("templating");
    assert!(variables.iter().any(|v| v["name"] == "instance"), "{variables:?}");
    for panel in dashboard["panels"].as_array().expect("panels") {
        assert_eq!(panel["datasource"]["uid"], "${DS_PROMETHEUS}", "{}", panel["title"]);
    }
    for (title, expr) in queries(&dashboard) {
        assert!(
            expr.contains("instance=~\"$instance\"") || title.starts_with("variable"),
            "{title}: {expr}"
        );
    }
}

#[test]
fn a_counter_is_queried_by_its_total() {
    let scrape = "# TYPE gcud_commands counter\ngcud_commands_total{outcome=\"result\"} 1\n\
                  # TYPE gcud_port_open gauge\n# TYPE gcud_wait histogram\n# EOF\n";
    let names = exported(scrape);
    assert!(names.contains("gcud_commands_total") && names.contains("gcud_port_open"));
    assert!(names.contains("gcud_wait_bucket") && names.contains("gcud_wait_count"));
    assert!(
        !names.contains("gcud_commands"),
        "a counter's family name is no series: {names:?}"
    );
    assert!(!names.contains("gcud_wait"), "{names:?}");
}

#[test]
fn metric_names_are_found_in_promql() {
    assert_eq!(
        metric_names("sum by (outcome) (rate(gcud_commands_total{instance=~\"$i\"}[5m])) / gcud_uptime_ms"),
        ["gcud_commands_total", "gcud_uptime_ms"]
    );
}
