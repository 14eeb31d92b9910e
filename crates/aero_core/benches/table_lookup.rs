//! Single-point 4-D lookup: the simulator's real-time path (floor: <= 50 ns).
use aero_core::table::{Axis, Table};
use criterion::{criterion_group, criterion_main, Criterion};
use std::hint::black_box;

fn table_4d() -> Table {
    let axes = vec![
        Axis::new("alpha", (0..30).map(|i| -10.0 + i as f64 * 1.5).collect()).expect("axis"),
        Axis::new("beta", (0..13).map(|i| -30.0 + i as f64 * 5.0).collect()).expect("axis"),
        Axis::new("flap", vec![0.0, 5.0, 10.0, 15.0, 35.0]).expect("axis"),
        Axis::new("da", (0..9).map(|i| -20.0 + i as f64 * 5.0).collect()).expect("axis"),
    ];
    let n: usize = 30 * 13 * 5 * 9;
    let values = (0..n).map(|i| ((i * 7919) % 1000) as f64 * 1e-3).collect();
    Table::new(axes, values).expect("table")
}

fn bench(c: &mut Criterion) {
    let t = table_4d();
    let pts: Vec<[f64; 4]> = (0..1024)
        .map(|i| {
            let f = i as f64;
            [
                -12.0 + (f * 0.731) % 50.0,
                -32.0 + (f * 1.37) % 64.0,
                (f * 0.53) % 36.0,
                -21.0 + (f * 2.11) % 42.0,
            ]
        })
        .collect();
    let mut k = 0usize;
    c.bench_function("table4d_single_point", |b| {
        b.iter(|| {
            k = (k + 1) & 1023;
            black_box(t.eval(black_box(&pts[k])))
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
