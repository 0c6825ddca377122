//! Landmark and target files: a NaN in a CSV landmark file (the JSON reader already refused it) and
//! points absurdly far away (a target 1e15 mm off) are errors naming the file and the line/field
//! (issue 49).
use laparo_register::io::{read_landmarks, read_targets};

#[test]
fn csv_landmarks_refuse_nan_inf_and_far_points() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("lm.csv");
    std::fs::write(&p, "group,x,y,z\nlip,0,0,0\nlip,1,2,3\nlip,4,5,6\n").unwrap();
    assert_eq!(read_landmarks(&p).unwrap()[0].points.len(), 3);
    for (bad, what) in [("nan", "non-finite"), ("inf", "non-finite"), ("-1e15", "beyond")] {
        std::fs::write(&p, format!("group,x,y,z\nlip,0,0,0\nlip,1,{bad},3\n")).unwrap();
        let e = read_landmarks(&p).unwrap_err().to_string();
        assert!(e.contains("lm.csv") && e.contains("line 3") && e.contains(what), "{bad}: {e}");
    }
}

#[test]
fn json_targets_refuse_points_absurdly_far() {
    let dir = tempfile::tempdir().unwrap();
    let l = dir.path().join("l.json");
    std::fs::write(&l, r#"{"groups": [{"name": "a", "points": [[0, 0, 0], [1, 0, 0], [0, 1, 0]]}]}"#).unwrap();
    let groups = read_landmarks(&l).unwrap();
    let t = dir.path().join("t.json");
    std::fs::write(&t, r#"{"groups": [{"name": "a", "points": [[0, 0, 0], [1, 0, 0], [0, 1, 1e15]]}]}"#).unwrap();
    let e = read_targets(&t, &groups).unwrap_err().to_string();
    assert!(e.contains("t.json") && e.contains("groups[0].points[2]") && e.contains("beyond"), "{e}");
    std::fs::write(&t, r#"{"groups": [{"name": "a", "points": [[0, 0, 0], [1, 0, 0], [0, 1, 10]]}]}"#).unwrap();
    assert!(read_targets(&t, &groups).is_ok());
    // a target surface (OBJ) 1e15 mm away
    let obj = dir.path().join("t.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 1e15\nf 1 2 3\n").unwrap();
    let e = read_targets(&obj, &groups).unwrap_err().to_string();
    assert!(e.contains("t.obj") && e.contains("vertex 2") && e.contains("beyond"), "{e}");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 10\nf 1 2 3\n").unwrap();
    assert!(read_targets(&obj, &groups).is_ok());
}
