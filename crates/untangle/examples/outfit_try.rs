use untangle::implicit::*;
fn main() {
    let shared = std::path::Path::new("/work/shared");
    let names: Vec<String> = std::env::args().skip(2).collect();
    let sub: usize = std::env::args().nth(1).unwrap().parse().unwrap();
    let nm: Vec<&str> = names.iter().map(|s| s.as_str()).collect();
    let (body, garments) = untangle::scenes::outfit::arcsim_outfit(shared, &nm, sub).unwrap();
    let refs: Vec<&untangle::mesh::Mesh> = garments.iter().collect();
    let pos0: Vec<_> = garments.iter().map(|m| m.positions.clone()).collect();
    println!("before: {:?}", verify(Some(&body), &refs, &pos0).unwrap());
    let inputs: Vec<GarmentInput> = garments
        .iter()
        .map(|m| GarmentInput {
            mesh: m,
            thickness: 0.005,
            weight: 1.0,
        })
        .collect();
    let t = std::time::Instant::now();
    let out = untangle_layers(Some(&body), &inputs, &Params::default(), &|_| {}).unwrap();
    println!(
        "time {:.0} ms body {:.0}",
        t.elapsed().as_secs_f64() * 1e3,
        out.body_field_ms
    );
    for r in &out.reports {
        println!("{r:?}");
    }
    println!(
        "after: {:?}",
        verify(Some(&body), &refs, &out.positions).unwrap()
    );
    for (m, p) in garments.iter().zip(&out.positions) {
        let mm = untangle::mesh::Mesh {
            positions: p.clone(),
            ..m.clone()
        };
        untangle::mesh::obj::write_obj(
            std::path::Path::new(&format!("/tmp/out_{}.obj", m.name)),
            &mm,
            None,
            "",
        )
        .unwrap();
        untangle::mesh::obj::write_obj(
            std::path::Path::new(&format!("/tmp/in_{}.obj", m.name)),
            m,
            None,
            "",
        )
        .unwrap();
    }
    untangle::mesh::obj::write_obj(std::path::Path::new("/tmp/body.obj"), &body, None, "").unwrap();
}
