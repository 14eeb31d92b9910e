//! DAVE-ML XML to a [`DaveModel`]: variables, breakpoints, tables, functions,
//! the evaluation order and the check cases. Every error names the element and
//! its line.

use std::collections::HashMap;
use std::sync::Arc;

use super::check::parse_check_data;
use super::mathml;
use super::model::{DaveModel, Def, Locator, Variable};
use super::uncertainty;
use super::{child, elements, parse_document, parse_numbers, text_of, Node, NodeId, Source};
use crate::error::{AeroError, Result};
use crate::table::{Axis, Extrapolation, Table, MAX_DIMS};
use crate::text::shown;

fn opt_f64(src: &Source, node: Node<'_>, attr: &str) -> Result<Option<f64>> {
    match node.attribute(attr) {
        None => Ok(None),
        Some(s) => s.trim().parse::<f64>().map(Some).map_err(|_| {
            src.err(
                node,
                format!("attribute {attr}=\"{}\" is not a number", shown(s)),
            )
        }),
    }
}

fn req_attr<'a>(src: &Source, node: Node<'a>, attr: &str) -> Result<&'a str> {
    node.attribute(attr)
        .ok_or_else(|| src.err(node, format!("lacks the required attribute '{attr}'")))
}

/// Parse a whole DAVE-ML document.
pub(crate) fn parse(text: &str, file: &str) -> Result<DaveModel> {
    let doc = parse_document(text, file)?;
    let src = Source::new(file, text);
    let root = doc.root_element();
    if root.tag_name() != "DAVEfunc" {
        return Err(src.err(
            root,
            "is not a DAVE-ML document; its root element must be <DAVEfunc>",
        ));
    }
    let name = child(root, "fileHeader")
        .and_then(|h| h.attribute("name"))
        .map_or_else(
            || {
                std::path::Path::new(file)
                    .file_name()
                    .map_or_else(|| file.to_string(), |f| f.to_string_lossy().into_owned())
            },
            str::to_string,
        );

    // Variables.
    let mut vars = Vec::new();
    let mut by_id: HashMap<String, usize> = HashMap::new();
    let mut calcs: Vec<(usize, Node, Node)> = Vec::new();
    for v in elements(root).filter(|n| n.tag_name() == "variableDef") {
        let id = req_attr(&src, v, "varID")?.trim().to_string();
        if let Some(&prev) = by_id.get(&id) {
            let prev_line: usize = vars.get(prev).map_or(0, |p: &Variable| p.line);
            return Err(src.err(
                v,
                format!(
                    "varID '{}' is already declared on line {prev_line}; varIDs must be unique",
                    shown(&id)
                ),
            ));
        }
        let has = |tag: &str| child(v, tag).is_some();
        let var = Variable {
            id: id.clone(),
            name: v.attribute("name").unwrap_or(&id).to_string(),
            units: v.attribute("units").unwrap_or("").trim().to_string(),
            description: child(v, "description").map(text_of).unwrap_or_default(),
            is_input: has("isInput") || has("isControl") || has("isDisturbance"),
            is_output: has("isOutput"),
            is_std_aiaa: has("isStdAIAA"),
            initial_value: opt_f64(&src, v, "initialValue")?,
            min_value: opt_f64(&src, v, "minValue")?,
            max_value: opt_f64(&src, v, "maxValue")?,
            line: src.line(v),
        };
        if let (Some(lo), Some(hi)) = (var.min_value, var.max_value) {
            if lo > hi {
                return Err(src.err(v, format!("minValue {lo} exceeds maxValue {hi}")));
            }
        }
        by_id.insert(id, vars.len());
        if let Some(c) = child(v, "calculation") {
            calcs.push((vars.len(), v, c));
        }
        vars.push(var);
    }
    let n = vars.len();
    let mut defs: Vec<Def> = vec![Def::Free; n];
    let mut defined_at: Vec<usize> = vec![0; n];
    let resolve = |s: &str| by_id.get(s.trim()).copied();

    for (i, v, c) in calcs {
        let math = child(c, "math").ok_or_else(|| src.err(c, "holds no <math> element"))?;
        defs[i] = Def::Calc(mathml::calculation(&src, math, &resolve, v)?);
        defined_at[i] = src.line(c);
    }

    // Breakpoint sets, checked strictly increasing once: the tables using a
    // set share its breakpoints.
    let mut bps: HashMap<String, Axis> = HashMap::new();
    for b in root
        .descendants()
        .filter(|n| n.tag_name() == "breakpointDef")
    {
        let id = req_attr(&src, b, "bpID")?.trim().to_string();
        let vals_node = child(b, "bpVals").ok_or_else(|| src.err(b, "holds no <bpVals>"))?;
        let vals = parse_numbers(&src, vals_node)?;
        let axis = Axis::new(id.clone(), vals).map_err(|e| src.err(b, e.to_string()))?;
        bps.insert(id, axis);
    }

    // Shared gridded tables by gtID.
    let mut gts: HashMap<String, Node> = HashMap::new();
    for g in root
        .descendants()
        .filter(|n| n.tag_name() == "griddedTableDef")
    {
        if let Some(id) = g.attribute("gtID") {
            gts.insert(id.trim().to_string(), g);
        }
    }

    // Functions. The values of a gridded table are read once, however many
    // functions reference it (a griddedTableRef).
    let mut data: HashMap<NodeId, Arc<Vec<f64>>> = HashMap::new();
    for f in elements(root).filter(|n| n.tag_name() == "function") {
        let (dep, def) = function(&src, f, &resolve, &bps, &gts, &mut data)?;
        if defined_at[dep] != 0 {
            return Err(src.err(
                f,
                format!(
                    "defines variable '{}' which is already defined on line {}; a variable has one calculation or one function",
                    shown(&vars[dep].id), defined_at[dep]
                ),
            ));
        }
        defs[dep] = def;
        defined_at[dep] = src.line(f);
    }

    // Uncertainty of variables and of tables (checked against their nominal
    // values), and the provenance references.
    let known = |s: &str| by_id.contains_key(s.trim());
    let mut uncertainties = Vec::new();
    for v in elements(root).filter(|n| n.tag_name() == "variableDef") {
        if let Some(&i) = v.attribute("varID").and_then(|id| by_id.get(id.trim())) {
            uncertainties.extend(uncertainty::parse(&src, v, &vars[i], &defs[i], &known)?);
        }
    }
    for f in elements(root).filter(|n| n.tag_name() == "function") {
        let dep = child(f, "dependentVarRef")
            .and_then(|d| d.attribute("varID"))
            .and_then(|id| by_id.get(id.trim()).copied());
        let table = child(f, "functionDefn")
            .and_then(|d| elements(d).next())
            .and_then(|t| match t.tag_name() {
                "griddedTableRef" => t
                    .attribute("gtID")
                    .and_then(|id| gts.get(id.trim()).copied()),
                _ => Some(t),
            });
        if let (Some(i), Some(t)) = (dep, table) {
            uncertainties.extend(uncertainty::parse(&src, t, &vars[i], &defs[i], &known)?);
        }
    }
    uncertainty::check_provenance_refs(&src, root)?;

    let order = topological_order(&src, &vars, &defs, &defined_at)?;
    let locators = share_locators(&mut defs);
    let mut base = vec![f64::NAN; n];
    let mut required = Vec::new();
    for i in 0..n {
        match (vars[i].initial_value, &defs[i]) {
            (Some(x), Def::Free) => base[i] = limit(&vars[i], x),
            (None, Def::Free) => required.push(i),
            _ => {}
        }
    }
    let mut model = DaveModel {
        name,
        vars,
        defs,
        order,
        required,
        base,
        locators,
        by_id: by_id.clone(),
        shots: Vec::new(),
        uncertainties,
    };
    if let Some(cd) = child(root, "checkData") {
        model.shots = parse_check_data(&src, cd, &model)?;
    }
    Ok(model)
}

/// One [`Locator`] per distinct (variable, axis) pair among the tables, so a
/// point locates e.g. alpha in a breakpoint set once for all tables sharing it.
/// Found by hashing, in time linear in the tables: each distinct breakpoint
/// set is hashed by content once.
fn share_locators(defs: &mut [Def]) -> Vec<Locator> {
    /// (variable, axis name, breakpoint set, below, above, min, max).
    type Key = (usize, String, usize, u8, u8, Option<u64>, Option<u64>);
    let mut locators: Vec<Locator> = Vec::new();
    let mut by_alloc: HashMap<(usize, usize), usize> = HashMap::new();
    let mut by_content: HashMap<Vec<u64>, usize> = HashMap::new();
    let mut by_key: HashMap<Key, usize> = HashMap::new();
    for d in defs.iter_mut() {
        if let Def::Table { table, args, locs } = d {
            locs.clear();
            for (k, &var) in args.iter().enumerate() {
                let axis = &table.axes()[k];
                let bp = axis.breakpoints();
                let set = *by_alloc
                    .entry((bp.as_ptr() as usize, bp.len()))
                    .or_insert_with(|| {
                        let next = by_content.len();
                        *by_content
                            .entry(bp.iter().map(|x| x.to_bits()).collect())
                            .or_insert(next)
                    });
                let key = (
                    var,
                    axis.name.clone(),
                    set,
                    axis.below as u8,
                    axis.above as u8,
                    axis.min.map(f64::to_bits),
                    axis.max.map(f64::to_bits),
                );
                let l = *by_key.entry(key).or_insert_with(|| {
                    locators.push(Locator {
                        var,
                        axis: axis.clone(),
                    });
                    locators.len() - 1
                });
                locs.push(l);
            }
        }
    }
    locators
}

fn limit(v: &Variable, x: f64) -> f64 {
    let mut x = x;
    if let Some(lo) = v.min_value {
        x = x.max(lo);
    }
    if let Some(hi) = v.max_value {
        x = x.min(hi);
    }
    x
}

/// `extrapolate` of an independent variable: (below, above).
fn extrapolation(src: &Source, node: Node<'_>) -> Result<(Extrapolation, Extrapolation)> {
    use Extrapolation::{Hold, Linear};
    if let Some(i) = node.attribute("interpolate") {
        if i != "linear" {
            return Err(src.err(
                node,
                format!(
                    "interpolate=\"{}\" is not supported; only linear interpolation is",
                    shown(i)
                ),
            ));
        }
    }
    match node.attribute("extrapolate").map(str::trim) {
        None | Some("neither") => Ok((Hold, Hold)),
        Some("min") => Ok((Linear, Hold)),
        Some("max") => Ok((Hold, Linear)),
        Some("both") => Ok((Linear, Linear)),
        Some(other) => Err(src.err(
            node,
            format!(
                "extrapolate=\"{}\" is not one of neither, min, max, both",
                shown(other)
            ),
        )),
    }
}

struct IndepVar {
    var: usize,
    min: Option<f64>,
    max: Option<f64>,
    below: Extrapolation,
    above: Extrapolation,
}

fn var_ref(src: &Source, node: Node<'_>, resolve: &dyn Fn(&str) -> Option<usize>) -> Result<usize> {
    let id = req_attr(src, node, "varID")?;
    resolve(id).ok_or_else(|| {
        let id = shown(id);
        src.err(
            node,
            format!("unknown varID '{id}'; declare it with a <variableDef varID=\"{id}\">"),
        )
    })
}

fn function(
    src: &Source,
    f: Node<'_>,
    resolve: &dyn Fn(&str) -> Option<usize>,
    bps: &HashMap<String, Axis>,
    gts: &HashMap<String, Node>,
    data: &mut HashMap<NodeId, Arc<Vec<f64>>>,
) -> Result<(usize, Def)> {
    let fname = f.attribute("name").unwrap_or("");
    // Simple form: independentVarPts+ then dependentVarPts.
    if let Some(dep_pts) = child(f, "dependentVarPts") {
        let mut axes = Vec::new();
        let mut args = Vec::new();
        for ip in elements(f).filter(|n| n.tag_name() == "independentVarPts") {
            let var = var_ref(src, ip, resolve)?;
            let (below, above) = extrapolation(src, ip)?;
            let pts = parse_numbers(src, ip)?;
            let axis = Axis::new(ip.attribute("varID").unwrap_or(""), pts)
                .map_err(|e| src.err(ip, e.to_string()))?
                .with_extrapolation(below, above);
            axes.push(axis);
            args.push(var);
        }
        let dep = var_ref(src, dep_pts, resolve)?;
        let values = parse_numbers(src, dep_pts)?;
        if axes.is_empty() || axes.len() > MAX_DIMS {
            return Err(src.err(
                f,
                format!("has {} independentVarPts; give 1 to {MAX_DIMS}", axes.len()),
            ));
        }
        let table = Table::new(axes, values).map_err(|e| src.err(dep_pts, e.to_string()))?;
        return Ok((
            dep,
            Def::Table {
                table,
                args,
                locs: Vec::new(),
            },
        ));
    }

    let mut ivs = Vec::new();
    for r in elements(f).filter(|n| n.tag_name() == "independentVarRef") {
        let var = var_ref(src, r, resolve)?;
        let (below, above) = extrapolation(src, r)?;
        let min = opt_f64(src, r, "min")?;
        let max = opt_f64(src, r, "max")?;
        ivs.push((
            r,
            IndepVar {
                var,
                min,
                max,
                below,
                above,
            },
        ));
    }
    let dep_node = child(f, "dependentVarRef")
        .ok_or_else(|| src.err(f, "has no <dependentVarRef> (or <dependentVarPts>)"))?;
    let dep = var_ref(src, dep_node, resolve)?;
    let defn = child(f, "functionDefn").ok_or_else(|| src.err(f, "has no <functionDefn>"))?;
    let tnode = elements(defn).next().ok_or_else(|| {
        src.err(
            defn,
            "is empty; give a griddedTableDef, griddedTable or griddedTableRef",
        )
    })?;
    let table_node = match tnode.tag_name() {
        "griddedTableDef" | "griddedTable" => tnode,
        "griddedTableRef" => {
            let id = req_attr(src, tnode, "gtID")?.trim();
            *gts.get(id).ok_or_else(|| {
                let id = shown(id);
                src.err(
                    tnode,
                    format!("unknown gtID '{id}'; no <griddedTableDef gtID=\"{id}\"> in the file"),
                )
            })?
        }
        other => {
            return Err(src.err(
                tnode,
                format!(
                    "<{}> is not supported; only gridded tables are (function '{}')",
                    shown(other),
                    shown(fname)
                ),
            ))
        }
    };
    let refs_node = child(table_node, "breakpointRefs")
        .ok_or_else(|| src.err(table_node, "has no <breakpointRefs>"))?;
    let refs: Vec<Node> = elements(refs_node)
        .filter(|n| n.tag_name() == "bpRef")
        .collect();
    if refs.len() != ivs.len() {
        return Err(src.err(
            f,
            format!(
                "has {} independentVarRef but its table (line {}) has {} bpRef; give one independent variable per breakpoint set",
                ivs.len(),
                src.line(table_node),
                refs.len()
            ),
        ));
    }
    if ivs.is_empty() || ivs.len() > MAX_DIMS {
        return Err(src.err(
            f,
            format!(
                "has {} independent variables; give 1 to {MAX_DIMS}",
                ivs.len()
            ),
        ));
    }
    let mut axes = Vec::with_capacity(refs.len());
    let mut args = Vec::with_capacity(refs.len());
    for (r, (iv_node, iv)) in refs.iter().zip(ivs) {
        let id = req_attr(src, *r, "bpID")?.trim();
        let mut axis = bps
            .get(id)
            .ok_or_else(|| {
                let id = shown(id);
                src.err(
                    *r,
                    format!("unknown bpID '{id}'; no <breakpointDef bpID=\"{id}\"> in the file"),
                )
            })?
            .clone();
        axis.name = iv_node.attribute("varID").unwrap_or(id).to_string();
        let axis = axis
            .with_extrapolation(iv.below, iv.above)
            .with_limits(iv.min, iv.max)
            .map_err(|e| src.err(iv_node, e.to_string()))?;
        axes.push(axis);
        args.push(iv.var);
    }
    let data_node =
        child(table_node, "dataTable").ok_or_else(|| src.err(table_node, "has no <dataTable>"))?;
    let values = match data.get(&data_node.id()) {
        Some(v) => v.clone(),
        None => {
            let v = Arc::new(parse_numbers(src, data_node)?);
            data.insert(data_node.id(), v.clone());
            v
        }
    };
    let table = Table::from_shared(axes, values).map_err(|e| src.err(table_node, e.to_string()))?;
    Ok((
        dep,
        Def::Table {
            table,
            args,
            locs: Vec::new(),
        },
    ))
}

fn dependencies(def: &Def) -> Vec<usize> {
    match def {
        Def::Free => Vec::new(),
        Def::Calc(e) => {
            let mut v = Vec::new();
            e.variables(&mut v);
            v
        }
        Def::Table { args, .. } => args.clone(),
    }
}

/// Depth-first topological order of the computed variables; a cycle is an
/// error naming its variables in order.
fn topological_order(
    src: &Source,
    vars: &[Variable],
    defs: &[Def],
    defined_at: &[usize],
) -> Result<Vec<usize>> {
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Active,
        Done,
    }
    let n = vars.len();
    let deps: Vec<Vec<usize>> = defs.iter().map(dependencies).collect();
    let mut mark = vec![Mark::New; n];
    let mut order = Vec::with_capacity(n);
    for start in 0..n {
        if mark[start] != Mark::New {
            continue;
        }
        // Explicit stack of (node, next dependency index).
        let mut stack: Vec<(usize, usize)> = vec![(start, 0)];
        mark[start] = Mark::Active;
        while let Some(top) = stack.last_mut() {
            let v = top.0;
            let next = deps[v].get(top.1).copied();
            if let Some(d) = next {
                top.1 += 1;
                match mark[d] {
                    Mark::New => {
                        mark[d] = Mark::Active;
                        stack.push((d, 0));
                    }
                    Mark::Active => {
                        let pos = stack.iter().position(|&(s, _)| s == d).unwrap_or(0);
                        let mut cycle: Vec<String> = stack[pos..]
                            .iter()
                            .map(|&(s, _)| shown(&vars[s].id))
                            .collect();
                        cycle.push(shown(&vars[d].id));
                        // A long cycle is shown by its ends, to keep the message one short line.
                        let ends = if cycle.len() > 12 {
                            format!(
                                "of {} variables {} -> ... -> {}",
                                cycle.len() - 1,
                                cycle[..5].join(" -> "),
                                cycle[cycle.len() - 5..].join(" -> ")
                            )
                        } else {
                            cycle.join(" -> ")
                        };
                        return Err(AeroError::parse(
                            src.file.clone(),
                            defined_at[d],
                            format!(
                                "<variableDef varID=\"{}\">: dependency cycle {ends}; break it so no variable depends on itself",
                                shown(&vars[d].id),
                            ),
                        ));
                    }
                    Mark::Done => {}
                }
            } else {
                mark[v] = Mark::Done;
                if !matches!(defs[v], Def::Free) {
                    order.push(v);
                }
                stack.pop();
            }
        }
    }
    Ok(order)
}
