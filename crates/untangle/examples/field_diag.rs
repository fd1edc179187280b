use untangle::geom::Vec3;
use untangle::implicit::*;
fn main() {
    let shared = std::path::Path::new("/work/shared");
    let names: Vec<String> = std::env::args().skip(2).collect();
    let sub: usize = std::env::args().nth(1).unwrap().parse().unwrap();
    let nm: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
    let (body, garments) = untangle::scenes::outfit::arcsim_outfit(shared, &nm, sub).unwrap();
    let c = body.positions.iter().sum::<Vec3>() / body.positions.len() as f64;
    let bf = layers::build_field(&body, &c, true, &FieldParams::default()).unwrap();
    let e: Vec<f64> = body
        .positions
        .iter()
        .map(|p| bf.field(p).unwrap().0)
        .collect();
    println!(
        "body iso max {:.4} inside centre {:?}",
        e.iter().fold(0.0f64, |a, b| a.max(b.abs())),
        bf.field(&c).map(|x| x.0)
    );
    for m in &garments {
        let f = layers::build_field(m, &c, false, &FieldParams::default()).unwrap();
        let e: Vec<f64> = m
            .positions
            .iter()
            .map(|p| f.field(p).map_or(f64::NAN, |x| x.0))
            .collect();
        let infl = m.positions.iter().filter(|p| f.influences(p)).count();
        let mut ae: Vec<f64> = e.iter().map(|x| x.abs()).collect();
        ae.sort_by(f64::total_cmp);
        println!("{}: n {} iso median {:.4} p95 {:.4} max {:.4}; own vertices influenced {}/{}; f at torso {:?}; body verts inside f: {}",
          m.name, m.positions.len(), ae[ae.len()/2], ae[ae.len()*95/100], ae[ae.len()-1], infl, m.positions.len(),
          f.field(&untangle::scenes::outfit::TORSO).map(|x| x.0),
          body.positions.iter().filter(|p| f.field(p).map_or(false, |x| x.0 < 0.0)).count());
    }
}
