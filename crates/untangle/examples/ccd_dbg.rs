use untangle::geom::ccd::*;
use untangle::geom::ccd_queries::read_queries;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let o = CcdOptions::default();
    let qs = read_queries(std::path::Path::new(&args[1])).unwrap();
    let ee = args[1].contains("edge-edge");
    let mut v = vec![];
    for (i, q) in qs.iter().enumerate() {
        let t = std::time::Instant::now();
        let mut h = None;
        for _ in 0..20 {
            h = if ee {
                edge_edge_impact(&q.x0, &q.x1, 0.0, &o)
            } else {
                vertex_triangle_impact(&q.x0, &q.x1, 0.0, &o)
            };
        }
        v.push((t.elapsed().as_secs_f64() * 1e6 / 20.0, i, q.truth, h));
    }
    let tot: f64 = v.iter().map(|x| x.0).sum();
    v.sort_by(|a, b| b.0.partial_cmp(&a.0).unwrap());
    println!("total {tot:.0} us");
    for x in &v[..8] {
        println!("{:.1}us q{} truth={} {:?}", x.0, x.1, x.2, x.3);
    }
    if args.len() > 2 {
        let q = &qs[v[0].1];
        println!("{:?}\n{:?}", q.x0, q.x1);
    }
}
