// scratch: error of an image against a reference, by 8x6 blocks and by reference brightness
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let (w, h, img) = portalview::io::read_exr(std::path::Path::new(&a[1])).unwrap();
    let (_, _, rf) = portalview::io::read_exr(std::path::Path::new(&a[2])).unwrap();
    let n = img.len() as f64 * 3.0;
    let mut total = 0.0;
    let mut blocks = vec![0.0f64; 48];
    let mut bright = vec![0.0f64; 6];
    for (k, (x, r)) in img.iter().zip(&rf).enumerate() {
        let d = *x - *r;
        let e = (d.x * d.x + d.y * d.y + d.z * d.z) as f64 / n;
        total += e;
        let (i, j) = (k as u32 % w, k as u32 / w);
        blocks[(j * 6 / h * 8 + i * 8 / w) as usize] += e;
        let l = (r.x + r.y + r.z) / 3.0;
        let b = if l < 0.1 {
            0
        } else if l < 0.3 {
            1
        } else if l < 1.0 {
            2
        } else if l < 3.0 {
            3
        } else if l < 10.0 {
            4
        } else {
            5
        };
        bright[b] += e;
    }
    println!("MSE {total:.3e}");
    for j in 0..6 {
        println!(
            "{}",
            (0..8)
                .map(|i| format!("{:5.1}", 100.0 * blocks[j * 8 + i] / total))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    println!(
        "by ref lum <0.1,<0.3,<1,<3,<10,>10: {}",
        bright
            .iter()
            .map(|b| format!("{:.1}%", 100.0 * b / total))
            .collect::<Vec<_>>()
            .join(" ")
    );
}
