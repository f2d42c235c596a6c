//! Rooms a reader takes in at once (issue 37, "What to build"): no non-test
//! source file over 700 lines and no function over 120 lines in the
//! binaries (`bins/`) and the crates (`crates/`), the protocol crate left
//! out as the issue leaves it out. Test code is left out too: `tests/`,
//! `benches/`, `examples/` directories and `tests.rs` test modules.
//! Functions are measured on the syntax tree (`syn` with span locations),
//! from the first line of the signature to the closing brace: free
//! functions, methods of `impl` blocks and provided methods of traits, at
//! any nesting. Tables declared by macro have no function bodies and so
//! are excepted naturally. The failure names every offender.
//!
//! And the router core's rooms import in one direction (issue 48): no
//! circle among the modules of `crates/gcu/src`, read on the syntax tree
//! (`crate::module` in paths and `use` trees, test code left out); the
//! failure names the circle and the file of each import in it.

use std::path::{Path, PathBuf};

use syn::spanned::Spanned;
use syn::visit::Visit;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
/// The longest non-test source file, in lines.
const MAX_FILE_LINES: usize = 700;
/// The longest function, in lines.
const MAX_FN_LINES: usize = 120;
/// Top-level directories walked.
const WALKED: [&str; 2] = ["bins", "crates"];
/// Left out of the limits: the protocol crate, as issue 37 leaves it out.
const LEFT_OUT: [&str; 1] = ["crates/protocol"];
/// Directory names whose contents are test, bench or example code.
const TEST_DIRS: [&str; 4] = ["tests", "benches", "examples", "target"];

/// Every `.rs` file under `dir` that is not test code, sorted.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        let relative = relative(&path);
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if LEFT_OUT.contains(&relative.as_str()) {
            continue;
        }
        if path.is_dir() {
            if !TEST_DIRS.contains(&name) {
                sources(&path, out);
            }
        } else if name.ends_with(".rs") && name != "tests.rs" {
            out.push(path);
        }
    }
}

/// A path relative to the workspace root, with `/` separators.
fn relative(path: &Path) -> String {
    let rel = path.strip_prefix(ROOT).unwrap_or(path);
    rel.components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join("/")
}

/// Collects `(name, first line, lines)` of every function with a body.
#[derive(Default)]
struct Functions {
    found: Vec<(String, usize, usize)>,
}

impl Functions {
    fn record(&mut self, name: String, span: proc_macro2::Span) {
        let (start, end) = (span.start().line, span.end().line);
        self.found.push((name, start, end + 1 - start));
    }
}

/// Whether an item is compiled for tests only (`#[cfg(test)]`).
fn test_only(attrs: &[syn::Attribute]) -> bool {
    attrs
        .iter()
        .any(|a| a.path().is_ident("cfg") && a.parse_args::<syn::Ident>().is_ok_and(|i| i == "test"))
}

impl<'ast> Visit<'ast> for Functions {
    fn visit_item_mod(&mut self, m: &'ast syn::ItemMod) {
        if !test_only(&m.attrs) {
            syn::visit::visit_item_mod(self, m);
        }
    }

    fn visit_item_fn(&mut self, f: &'ast syn::ItemFn) {
        self.record(f.sig.ident.to_string(), f.span());
        syn::visit::visit_item_fn(self, f);
    }

    fn visit_impl_item_fn(&mut self, f: &'ast syn::ImplItemFn) {
        self.record(f.sig.ident.to_string(), f.span());
        syn::visit::visit_impl_item_fn(self, f);
    }

    fn visit_trait_item_fn(&mut self, f: &'ast syn::TraitItemFn) {
        if f.default.is_some() {
            self.record(f.sig.ident.to_string(), f.span());
        }
        syn::visit::visit_trait_item_fn(self, f);
    }
}

/// The offences of one file: its length, then each long function.
fn offences(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let file = relative(path);
    let mut found = Vec::new();
    let lines = text.lines().count();
    if lines > MAX_FILE_LINES {
        found.push(format!("{file}: {lines} lines (limit {MAX_FILE_LINES})"));
    }
    let tree = syn::parse_file(&text).unwrap_or_else(|e| panic!("{file}: does not parse: {e}"));
    let mut functions = Functions::default();
    functions.visit_file(&tree);
    for (name, line, length) in functions.found {
        if length > MAX_FN_LINES {
            found.push(format!(
                "{file}:{line}: fn {name} is {length} lines (limit {MAX_FN_LINES})"
            ));
        }
    }
    found
}

#[test]
fn no_source_file_over_700_lines_nor_function_over_120() {
    let mut files = Vec::new();
    for dir in WALKED {
        sources(&Path::new(ROOT).join(dir), &mut files);
    }
    assert!(
        files.len() > 50,
        "walked only {} files: the walk is broken",
        files.len()
    );
    let found: Vec<String> = files.iter().flat_map(|f| offences(f)).collect();
    assert!(
        found.is_empty(),
        "{} rooms past a reader's size (issue 37):\n{}",
        found.len(),
        found.join("\n")
    );
}

/// The measure itself: a function of known length is found and measured
/// from its signature to its closing brace, inside an `impl` and a module.
#[test]
fn the_measure_counts_a_function_from_signature_to_closing_brace() {
    let text = "mod m {\n    struct S;\n    impl S {\n        fn three(&self) {\n            let _ = 1;\n        }\n    }\n}\nfn one() {}\n";
    let tree = syn::parse_file(text).expect("parses");
    let mut functions = Functions::default();
    functions.visit_file(&tree);
    assert_eq!(
        functions.found,
        vec![("three".to_owned(), 4, 3), ("one".to_owned(), 9, 1)]
    );
}

/// The top-level modules of `crates/gcu/src` each file's non-test code
/// names (`crate::NAME`), with the file that names it.
#[derive(Default)]
struct CrateImports {
    found: Vec<String>,
}

impl<'ast> Visit<'ast> for CrateImports {
    fn visit_item_mod(&mut self, m: &'ast syn::ItemMod) {
        if !test_only(&m.attrs) {
            syn::visit::visit_item_mod(self, m);
        }
    }

    fn visit_item_fn(&mut self, f: &'ast syn::ItemFn) {
        if !test_only(&f.attrs) {
            syn::visit::visit_item_fn(self, f);
        }
    }

    fn visit_path(&mut self, p: &'ast syn::Path) {
        let mut segments = p.segments.iter();
        if let (Some(first), Some(second)) = (segments.next(), segments.next()) {
            if first.ident == "crate" {
                self.found.push(second.ident.to_string());
            }
        }
        syn::visit::visit_path(self, p);
    }

    fn visit_use_path(&mut self, u: &'ast syn::UsePath) {
        if u.ident == "crate" {
            let mut names = Vec::new();
            use_names(&u.tree, &mut names);
            self.found.extend(names);
        }
        syn::visit::visit_use_path(self, u);
    }
}

/// The first names of a `use` tree (`crate::{a::X, b}`: `a`, `b`).
fn use_names(tree: &syn::UseTree, out: &mut Vec<String>) {
    match tree {
        syn::UseTree::Path(p) => out.push(p.ident.to_string()),
        syn::UseTree::Name(n) => out.push(n.ident.to_string()),
        syn::UseTree::Rename(r) => out.push(r.ident.to_string()),
        syn::UseTree::Group(g) => g.items.iter().for_each(|t| use_names(t, out)),
        syn::UseTree::Glob(_) => {}
    }
}

/// The circles of a directed graph (each found once, from its least node).
fn circles(graph: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>) -> Vec<Vec<String>> {
    fn walk(
        graph: &std::collections::BTreeMap<String, std::collections::BTreeSet<String>>,
        start: &str,
        path: &mut Vec<String>,
        found: &mut Vec<Vec<String>>,
    ) {
        let Some(last) = path.last().cloned() else { return };
        for next in graph.get(&last).into_iter().flatten() {
            if next == start {
                found.push(path.clone());
            } else if next.as_str() > start && !path.contains(next) {
                path.push(next.clone());
                walk(graph, start, path, found);
                path.pop();
            }
        }
    }
    let mut found = Vec::new();
    for start in graph.keys() {
        walk(graph, start, &mut vec![start.clone()], &mut found);
    }
    found
}

#[test]
fn the_router_cores_modules_import_no_circle() {
    use std::collections::{BTreeMap, BTreeSet};
    let src = Path::new(ROOT).join("crates/gcu/src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let module_of = |path: &Path| -> String {
        let rel = path.strip_prefix(&src).expect("under src");
        let first = rel.components().next().expect("a component");
        first.as_os_str().to_string_lossy().trim_end_matches(".rs").to_owned()
    };
    let modules: BTreeSet<String> = files.iter().map(|f| module_of(f)).filter(|m| m != "lib").collect();
    assert!(modules.len() > 10, "{modules:?}");
    let mut graph: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    let mut by_whom: BTreeMap<(String, String), String> = BTreeMap::new();
    for file in &files {
        let from = module_of(file);
        if from == "lib" {
            continue;
        }
        let text = std::fs::read_to_string(file).expect("source");
        let tree = syn::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", file.display()));
        let mut imports = CrateImports::default();
        imports.visit_file(&tree);
        for to in imports.found {
            if to != from && modules.contains(&to) {
                graph.entry(from.clone()).or_default().insert(to.clone());
                by_whom.entry((from.clone(), to)).or_insert_with(|| relative(file));
            }
        }
    }
    let found = circles(&graph);
    let named: Vec<String> = found
        .iter()
        .map(|c| {
            let steps: Vec<String> = c
                .iter()
                .zip(c.iter().cycle().skip(1))
                .map(|(a, b)| format!("{a} -> {b} ({})", by_whom[&(a.clone(), b.clone())]))
                .collect();
            steps.join(", ")
        })
        .collect();
    assert!(
        named.is_empty(),
        "import circles in crates/gcu/src:\n{}",
        named.join("\n")
    );
}

/// The circle finder finds a circle and names it from its least node.
#[test]
fn the_circle_finder_finds_circles_and_nothing_else() {
    let graph = |edges: &[(&str, &str)]| {
        let mut g: std::collections::BTreeMap<String, std::collections::BTreeSet<String>> = Default::default();
        for (a, b) in edges {
            g.entry(a.to_string()).or_default().insert(b.to_string());
        }
        g
    };
    assert!(circles(&graph(&[("a", "b"), ("b", "c"), ("a", "c")])).is_empty());
    assert_eq!(
        circles(&graph(&[
            ("config", "govern"),
            ("govern", "config"),
            ("govern", "types")
        ])),
        [vec!["config".to_string(), "govern".to_string()]]
    );
}
