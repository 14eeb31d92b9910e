use aero_core::lsq::{ols, OlsOptions};
use std::time::Instant;
fn main() {
    let (n, p) = (1_000_000usize, 12usize);
    let mut s = 88172645463325252u64;
    let mut x = vec![0.0; n * p];
    for v in x.iter_mut() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        *v = (s % 100000) as f64 / 50000.0 - 1.0;
    }
    for i in 0..n {
        x[i * p] = 1.0;
    }
    let z: Vec<f64> = (0..n)
        .map(|i| x[i * p..(i + 1) * p].iter().sum::<f64>() + ((i * 7919 % 101) as f64) * 0.01)
        .collect();
    for colored in [false, true] {
        for _ in 0..6 {
            let t = Instant::now();
            let f = ols(
                &x,
                n,
                p,
                &z,
                &OlsOptions {
                    colored,
                    ..Default::default()
                },
            )
            .unwrap();
            println!(
                "colored={colored} {:.1} ms r2 {}",
                t.elapsed().as_secs_f64() * 1e3,
                f.r2
            );
        }
    }
}
