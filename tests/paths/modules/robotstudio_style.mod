MODULE Module1
    CONST robtarget Target_10:=[[-12.5,40,0],[0.5,0.5,-0.5,0.5],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
    CONST robtarget Target_20:=[[-12.5,90,0],[0.5,0.5,-0.5,0.5],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
    CONST robtarget Target_30:=[[-12.5,140,2.5E-01],[0.5,0.5,-0.5,0.5],[-1,0,-1,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
    TASK PERS wobjdata Workobject_1:=[FALSE,TRUE,"",[[400,100,0],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    TASK PERS tooldata MyTool:=[TRUE,[[0,0,120],[1,0,0,0]],[1,[0,0,1],[1,0,0,0],0,0,0]];
    !***********************************************************
    !
    ! Procedure main
    !
    !   This is the entry point of your program
    !
    !***********************************************************
    PROC main()
        !Add your code here
        Path_10;
    ENDPROC
    PROC Path_10()
        MoveL Target_10,v1000,z100,MyTool\WObj:=Workobject_1;
        MoveL Target_20,v1000,z100,MyTool\WObj:=Workobject_1;
        MoveL Target_30,v1000,z100,MyTool\WObj:=Workobject_1;
    ENDPROC
ENDMODULE
