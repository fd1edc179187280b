use untangle::geom::ccd::*;
use untangle::geom::ccd_queries::read_queries;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let qs = read_queries(std::path::Path::new(&args[1])).unwrap();
    let q = &qs[args[2].parse::<usize>().unwrap()];
    let o = CcdOptions::default();
    let n: usize = args.get(3).map_or(1, |s| s.parse().unwrap());
    let mut h = None;
    for _ in 0..n {
        h = if args[1].contains("edge-edge") {
            edge_edge_impact(&q.x0, &q.x1, 0.0, &o)
        } else {
            vertex_triangle_impact(&q.x0, &q.x1, 0.0, &o)
        };
    }
    println!("{:?} truth {}", h, q.truth);
}
